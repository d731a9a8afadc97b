"""The frame journal: one JSON line per committed frame, appended after its files exist.

A frame is committed when, and only when, its line is in ``journal.jsonl``. Lines are
written whole, flushed and fsynced; a ``kill -9`` can leave at most one truncated last
line, which the reader drops (and ``truncate_torn_tail`` cuts off before appending again).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from satsight.errors import SatsightError

JOURNAL_NAME = "journal.jsonl"
_TAIL_BLOCK_BYTES = 1 << 16


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


def iter_journal(root: Path) -> Iterator[tuple[dict, int, int]]:
    """(record, byte offset, byte length) of each committed line of ``root/journal.jsonl``,
    in file order, read as a stream (a 10^6-frame journal is several GB).

    A last line without its newline is a torn write, not a commit, and is left out; a line
    that ends with a newline but is not a frame record is corruption and is an error that
    names the line.
    """
    path = Path(root) / JOURNAL_NAME
    if not path.is_file():
        return
    offset = 0
    with open(path, "rb") as stream:
        for number, line in enumerate(stream, start=1):
            if not line.endswith(b"\n"):
                return  # torn last line
            try:
                record = json.loads(line)
                if not isinstance(record, dict) or "frame_index" not in record:
                    raise ValueError("not a frame record")
            except (ValueError, UnicodeDecodeError) as error:
                raise SatsightError(
                    f"{path}, line {number}: not a frame record ({error}); the journal is "
                    "corrupt: remove the line or regenerate the dataset"
                ) from None
            yield record, offset, len(line)
            offset += len(line)


def read_journal(root: Path) -> list[dict]:
    """Every committed frame record of ``root/journal.jsonl``, in file order."""
    return [record for record, _, _ in iter_journal(root)]


class JournalFrames(Sequence):
    """Frame records read on demand from journal lines at known byte offsets.

    offsets, lengths: where each frame's line lies. indices: each one's frame index (by
    default 0, 1, 2, ...: a closed journal). A dataset of 10^6 frames holds several GB of
    records; this keeps three integers per frame in memory and parses a record only when
    it is asked for.
    """

    def __init__(
        self,
        path: Path,
        offsets: np.ndarray,
        lengths: np.ndarray,
        indices: np.ndarray | None = None,
    ):
        self.path = Path(path)
        self.offsets = np.asarray(offsets, dtype=np.int64)
        self.lengths = np.asarray(lengths, dtype=np.int64)
        self.indices = (
            np.arange(len(self.offsets)) if indices is None else np.asarray(indices, np.int64)
        )

    def __len__(self) -> int:
        return len(self.offsets)

    def raw(self, index: int) -> bytes:
        """The journal line of the index-th frame, newline included."""
        with open(self.path, "rb") as stream:
            stream.seek(int(self.offsets[index]))
            return stream.read(int(self.lengths[index]))

    def raw_lines(self, positions: Iterable[int] | None = None) -> Iterator[bytes]:
        """The journal lines at ``positions`` (default: every frame, in order), read
        through one open file."""
        if positions is None:
            positions = range(len(self))
        with open(self.path, "rb") as stream:
            for position in positions:
                stream.seek(int(self.offsets[position]))
                yield stream.read(int(self.lengths[position]))

    def records_at(self, positions: Iterable[int]) -> Iterator[dict]:
        """The records at ``positions``, parsed one at a time."""
        for line in self.raw_lines(positions):
            yield json.loads(line)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError(index)
        return json.loads(self.raw(index))

    def __iter__(self) -> Iterator[dict]:
        for line in self.raw_lines():
            yield json.loads(line)


def sorted_journal_frames(root: Path) -> JournalFrames:
    """The frames of a closed dataset's journal (one line per frame, in frame order),
    indexed by a scan for line ends, without parsing a record."""
    offsets, lengths, offset = [], [], 0
    path = Path(root) / JOURNAL_NAME
    with open(path, "rb") as stream:
        for line in stream:
            if not line.endswith(b"\n"):
                break
            offsets.append(offset)
            lengths.append(len(line))
            offset += len(line)
    return JournalFrames(path, np.array(offsets), np.array(lengths))


def journal_frames(root: Path, keep: Callable[[dict], bool] | None = None) -> JournalFrames:
    """The committed frames of a journal, sorted by frame index, the last line of a frame
    winning; ``keep(record)`` may leave a frame out (e.g. one whose files are missing)."""
    latest: dict[int, tuple[int, int]] = {}
    for record, offset, length in iter_journal(root):
        index = int(record["frame_index"])
        if keep is None or keep(record):
            latest[index] = (offset, length)
        else:
            latest.pop(index, None)
    order = sorted(latest)
    spans = np.array([latest[i] for i in order], dtype=np.int64).reshape(-1, 2)
    return JournalFrames(Path(root) / JOURNAL_NAME, spans[:, 0], spans[:, 1], np.array(order))


def truncate_torn_tail(root: Path) -> None:
    """Cut a torn (unterminated) last line off the journal, so appends start a fresh line.

    Reads backwards from the end in blocks: the journal of a large dataset is never read
    whole here.
    """
    path = Path(root) / JOURNAL_NAME
    if not path.is_file():
        return
    with open(path, "r+b") as stream:
        end = stream.seek(0, os.SEEK_END)
        if end == 0:
            return
        stream.seek(end - 1)
        if stream.read(1) == b"\n":
            return
        position = end
        while position > 0:
            start = max(0, position - _TAIL_BLOCK_BYTES)
            stream.seek(start)
            block = stream.read(position - start)
            newline = block.rfind(b"\n")
            if newline >= 0:
                position = start + newline + 1
                break
            position = start
        stream.truncate(position)
        stream.flush()
        os.fsync(stream.fileno())


class JournalWriter:
    """Appends committed frame records to ``root/journal.jsonl``, one fsynced line each."""

    def __init__(self, root: Path):
        self.path = Path(root) / JOURNAL_NAME
        truncate_torn_tail(root)
        self._stream = open(self.path, "ab")

    def append(self, record: dict) -> tuple[int, int]:
        """Append one record; its line's (byte offset, byte length) in the journal."""
        line = record_line(record)
        offset = self._stream.tell()
        self._stream.write(line)
        self._stream.flush()
        os.fsync(self._stream.fileno())
        return offset, len(line)

    def close(self) -> None:
        self._stream.close()

    def __enter__(self) -> JournalWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_lines_atomic(path: Path, lines: Iterable[bytes]) -> str:
    """Write ``lines`` to ``path`` through a temporary name and a rename; their SHA-256."""
    path = Path(path)
    tmp = temporary_name(path)
    digest = hashlib.sha256()
    try:
        with open(tmp, "wb") as stream:
            for line in lines:
                digest.update(line)
                stream.write(line)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return digest.hexdigest()


def temporary_name(path: Path) -> Path:
    """The temporary name a file is written under before it is renamed into place."""
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary name and a rename."""
    write_lines_atomic(path, (data,))
