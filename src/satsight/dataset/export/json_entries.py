"""JSON files written entry by entry: a dict or a list with one entry per line.

The per-image files of an export (BOP's ``scene_gt.json``, SPEED+'s ``train.json``, ...)
have one entry per image, 10^6 for a large dataset. ``JsonEntries`` writes them as the
images are exported, in the layout the all-at-once writers give (``bop_json_text``,
``speedplus.json_text``), without holding the entries.
"""

from __future__ import annotations

import json
from pathlib import Path


class JsonEntries:
    """A JSON dict (``add(key, value)``) or list (``append(value)``) written one entry per
    line::

        {
          "KEY": VALUE,
          "KEY": VALUE
        }

    (``{\\n}`` / ``[\\n]`` when empty). sort_keys: sort each value's keys. final_newline:
    end the file with a newline. A dict's keys must come in increasing order (the order
    of the all-at-once writer's sorted keys).
    """

    def __init__(
        self, path: Path, kind: type = dict, sort_keys: bool = False, final_newline: bool = False
    ):
        if kind not in (dict, list):
            raise TypeError(f"kind must be dict or list, not {kind!r}")
        self.kind, self.sort_keys, self.final_newline = kind, sort_keys, final_newline
        self.count = 0
        self._last_key = None
        self._stream = open(path, "w", encoding="utf-8")
        self._stream.write("{\n" if kind is dict else "[\n")

    def _dumps(self, value: object) -> str:
        return json.dumps(value, sort_keys=self.sort_keys, allow_nan=False)

    def _line(self, text: str) -> None:
        self._stream.write((",\n" if self.count else "") + text)
        self.count += 1

    def add(self, key: int | str, value: object) -> None:
        """Write one entry of a dict; ``key`` after every key written before."""
        if self.kind is not dict:
            raise TypeError("add() writes dict entries; use append() for a list")
        if self.count and not key > self._last_key:
            raise ValueError(f"keys must increase: {key!r} after {self._last_key!r}")
        self._line(f"  {json.dumps(str(key))}: {self._dumps(value)}")
        self._last_key = key

    def append(self, value: object) -> None:
        """Write one element of a list."""
        if self.kind is not list:
            raise TypeError("append() writes list elements; use add() for a dict")
        self._line(f"  {self._dumps(value)}")

    def close(self) -> None:
        end = "}" if self.kind is dict else "]"
        newline = "\n" if self.final_newline else ""
        self._stream.write(("\n" if self.count else "") + end + newline)
        self._stream.close()

    def __enter__(self) -> JsonEntries:
        return self

    def __exit__(self, kind, error, traceback) -> None:
        if kind is None:
            self.close()
        else:
            self._stream.close()  # an export that failed is removed whole
