"""The frames a run has committed: read back from the journal on resume (each frame's files
checked against their committed size and SHA-256), and where each lies in the journal."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from satsight.dataset.journal import JOURNAL_NAME, JournalFrames, file_checksum, journal_frames
from satsight.errors import SatsightError
from satsight.run.shard import Shard

# Threads that hash committed files on resume (hashlib releases the GIL), and how many
# frames they may hold at once.
HASH_THREADS = 4
_HASH_WINDOW = 4 * HASH_THREADS


def _damage(root: Path, record: dict) -> str | None:
    """What is wrong with a committed frame's files ("images/frame_000004.png missing",
    "... changed"), or None when each is there with its committed size and SHA-256."""
    for relative, checksum in record.get("checksums", {}).items():
        try:
            if (root / relative).stat().st_size != checksum["size_bytes"]:
                return f"{relative} changed"
            if file_checksum(root / relative)["sha256"] != checksum["sha256"]:
                return f"{relative} changed"
        except OSError:
            return f"{relative} missing"
    return None


def _bounded_map(function: Callable, items, threads: int, window: int) -> Iterator:
    """``map(function, items)`` on ``threads`` threads, in order, with at most ``window``
    items in flight (a 10^6-frame journal is never held whole)."""
    with ThreadPoolExecutor(threads, thread_name_prefix="satsight-hash") as pool:
        pending: deque = deque()
        for item in items:
            pending.append(pool.submit(function, item))
            if len(pending) >= window:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


class CommitTable:
    """Where each committed frame of a run (one shard's frames, or all) lies in the
    journal: two integers per frame, so that a 10^6-frame run keeps no records in memory."""

    def __init__(self, shard: Shard, frame_count: int):
        self.shard = shard
        self.frames = shard.frames(frame_count)
        self._offsets = np.full(len(self.frames), -1, dtype=np.int64)
        self._lengths = np.zeros(len(self.frames), dtype=np.int64)
        self.count = 0

    def _position(self, frame_index: int) -> int | None:
        position, remainder = divmod(frame_index - self.shard.index, self.shard.count)
        if remainder or not 0 <= position < len(self.frames):
            return None
        return position

    def __contains__(self, frame_index: int) -> bool:
        return self._position(frame_index) is not None

    def commit(self, frame_index: int, offset: int, length: int) -> None:
        position = self._position(frame_index)
        if self._offsets[position] < 0:
            self.count += 1
        self._offsets[position] = offset
        self._lengths[position] = length

    def todo(self) -> list[int]:
        """The frames not committed yet, in order."""
        return [self.frames[i] for i in np.flatnonzero(self._offsets < 0)]

    def journal_lines(self, root: Path) -> Iterator[bytes]:
        """Every frame's committed journal line, in frame order."""
        return JournalFrames(root / JOURNAL_NAME, self._offsets, self._lengths).raw_lines()


def committed_frames(root: Path, table: CommitTable) -> list[str]:
    """Enter in ``table`` the frames committed in ``root``'s journal whose files are all
    there with their committed size and SHA-256 (the last line of a frame wins); what is
    wrong with each frame left out (to be rendered again)."""

    def keep(record: dict) -> bool:
        index = int(record["frame_index"])
        if index not in table:
            raise SatsightError(
                f"{root / JOURNAL_NAME} holds frame {index}, which this run does not make "
                "(another shard's or scenario's); use the folder it was started for"
            )
        return True

    lines = journal_frames(root, keep)
    damaged = []
    records = iter(lines) if len(lines) else iter(())
    checks = _bounded_map(lambda record: _damage(root, record), records, HASH_THREADS,
                          _HASH_WINDOW)  # fmt: skip
    spans = zip(lines.indices, lines.offsets, lines.lengths, checks, strict=True)
    for index, offset, length, damage in spans:
        if damage is None:
            table.commit(int(index), int(offset), int(length))
        else:
            damaged.append(f"frame {index}: {damage}")
    return damaged
