"""The frame journal: one JSON line per committed frame, appended after its files exist.

A frame is committed when, and only when, its line is in ``journal.jsonl``. Lines are
written whole, flushed and fsynced; a ``kill -9`` can leave at most one truncated last
line, which the reader drops (and ``truncate_torn_tail`` cuts off before appending again).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from satsight.errors import SatsightError

JOURNAL_NAME = "journal.jsonl"


def file_checksum(path: Path) -> dict:
    """{sha256, size_bytes} of one file."""
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as stream:
        while chunk := stream.read(1 << 20):
            digest.update(chunk)
            size += len(chunk)
    return {"sha256": digest.hexdigest(), "size_bytes": size}


def bytes_checksum(data: bytes) -> dict:
    """{sha256, size_bytes} of bytes about to be written."""
    return {"sha256": hashlib.sha256(data).hexdigest(), "size_bytes": len(data)}


def record_line(record: dict) -> bytes:
    """One journal line: compact JSON, keys in the record's order, newline-terminated."""
    return (json.dumps(record, separators=(",", ":"), allow_nan=False) + "\n").encode("utf-8")


def read_journal(root: Path) -> list[dict]:
    """The committed frame records of ``root/journal.jsonl`` in file order.

    A torn last line (no newline, or not JSON) is not a commit and is dropped; a bad line
    before the last is corruption and is an error naming the line.
    """
    path = Path(root) / JOURNAL_NAME
    if not path.is_file():
        return []
    data = path.read_bytes()
    lines = data.split(b"\n")
    records = []
    for number, line in enumerate(lines, start=1):
        last = number == len(lines)
        if last and line == b"":
            break
        try:
            record = json.loads(line)
            if not isinstance(record, dict) or "frame_index" not in record:
                raise ValueError("not a frame record")
        except (ValueError, UnicodeDecodeError) as error:
            # Only the final piece, without its newline, can be a torn write.
            if number >= len(lines) - 1 and not data.endswith(b"\n"):
                break
            raise SatsightError(
                f"{path}, line {number}: not a frame record ({error}); the journal is "
                "corrupt: remove the line or regenerate the dataset"
            ) from None
        records.append(record)
    return records


def truncate_torn_tail(root: Path) -> None:
    """Cut a torn (unterminated) last line off the journal, so appends start a fresh line."""
    path = Path(root) / JOURNAL_NAME
    if not path.is_file():
        return
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        with open(path, "r+b") as stream:
            stream.truncate(data.rfind(b"\n") + 1)
            stream.flush()
            os.fsync(stream.fileno())


class JournalWriter:
    """Appends committed frame records to ``root/journal.jsonl``, one fsynced line each."""

    def __init__(self, root: Path):
        self.path = Path(root) / JOURNAL_NAME
        truncate_torn_tail(root)
        self._stream = open(self.path, "ab")

    def append(self, record: dict) -> None:
        self._stream.write(record_line(record))
        self._stream.flush()
        os.fsync(self._stream.fileno())

    def close(self) -> None:
        self._stream.close()

    def __enter__(self) -> JournalWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_sorted_journal(root: Path, records: list[dict]) -> bytes:
    """Rewrite the journal with ``records`` sorted by frame index (atomically); its bytes."""
    data = b"".join(record_line(r) for r in sorted(records, key=lambda r: r["frame_index"]))
    write_bytes_atomic(Path(root) / JOURNAL_NAME, data)
    return data


def temporary_name(path: Path) -> Path:
    """The temporary name a file is written under before it is renamed into place."""
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary name and a rename."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        with open(tmp, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
