"""The journal pass of ``satsight validate``: every journal record, in file order, fed to
the record checks, with labels.json parsed as a stream in step with them and hashed on the
way; where each journal line lies (three integers per line), for the labels pass to match
labels.json's frames with the journal's by frame index when they differ."""

from __future__ import annotations

import hashlib
import json
from array import array
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from satsight.dataset.journal import JOURNAL_NAME, iter_journal
from satsight.dataset.labels_stream import LabelsStream, LabelsStreamError
from satsight.dataset.problems import Findings
from satsight.dataset.reader import LABELS_NAME
from satsight.dataset.record_checks import RecordChecks, is_count, is_int
from satsight.errors import SatsightError

_READ_BYTES = 1 << 20
_INT64 = (-(1 << 63), 1 << 63)


def _key(value) -> str:
    """A frame index that is not an integer, as a hashable key (JSON text)."""
    return json.dumps(value, sort_keys=True)


def scan_journal(path: Path) -> tuple[str | None, int]:
    """The journal's SHA-256 and its number of committed (newline-terminated) lines;
    (None, 0) when it is missing."""
    digest, lines = hashlib.sha256(), 0
    try:
        with open(path, "rb") as stream:
            while chunk := stream.read(_READ_BYTES):
                digest.update(chunk)
                lines += chunk.count(b"\n")
    except OSError:
        return None, 0
    return digest.hexdigest(), lines


class JournalSpans:
    """Where each journal line lies (byte offset and length), by frame index: three
    integers per line. ``freeze`` before ``take``."""

    def __init__(self):
        self._index, self._offset, self._length = array("q"), array("q"), array("q")
        self._other: dict[str, tuple[int, int]] = {}  # frame indices that are not integers
        self._other_taken: set[str] = set()

    def add(self, frame_index, offset: int, length: int) -> None:
        if is_int(frame_index) and _INT64[0] <= frame_index < _INT64[1]:
            self._index.append(frame_index)
            self._offset.append(offset)
            self._length.append(length)
        else:
            self._other[_key(frame_index)] = (offset, length)  # the last line of a frame wins

    def freeze(self) -> None:
        """Sort by frame index; of the lines of one frame, the last wins."""
        index = np.array(self._index, dtype=np.int64)
        offset = np.array(self._offset, dtype=np.int64)
        length = np.array(self._length, dtype=np.int64)
        del self._index, self._offset, self._length
        order = np.lexsort((np.arange(len(index)), index))
        last = np.ones(len(order), dtype=bool)
        last[:-1] = index[order[1:]] != index[order[:-1]]
        keep = order[last]
        self.keys, self.offsets, self.lengths = index[keep], offset[keep], length[keep]
        self.taken = np.zeros(len(keep), dtype=bool)

    def take(self, frame_index) -> tuple[int, int] | None:
        """(offset, length) of a frame's journal line; None when there is none, or when it
        was taken before."""
        if is_int(frame_index) and _INT64[0] <= frame_index < _INT64[1]:
            i = int(np.searchsorted(self.keys, frame_index))
            if i < len(self.keys) and self.keys[i] == frame_index and not self.taken[i]:
                self.taken[i] = True
                return int(self.offsets[i]), int(self.lengths[i])
            return None
        key = _key(frame_index)
        if key not in self._other or key in self._other_taken:
            return None
        self._other_taken.add(key)
        return self._other[key]

    def untaken(self) -> Iterator:
        """Frame indices of the journal never taken, in increasing order."""
        for i in np.flatnonzero(~self.taken):
            yield int(self.keys[i])
        for key in self._other:
            if key not in self._other_taken:
                yield json.loads(key)


def header_differences(header: dict, manifest: dict) -> list[str]:
    """The keys whose values differ between labels.json's header and the manifest."""
    return sorted(k for k in set(header) | set(manifest) if header.get(k) != manifest.get(k))


class _InStep:
    """labels.json parsed as a stream in step with the journal records (``feed``): whether
    its frames are the records, one for one in order, and its header the manifest; its
    SHA-256 when it was read to its end (else None)."""

    def __init__(self, path: Path, manifest: dict):
        self.manifest = manifest
        self.digest = hashlib.sha256()
        self.labels = LabelsStream(path, self.digest)
        self.frames = self.labels.frames()
        self.equal = True
        self.sha256: str | None = None

    def feed(self, record: dict) -> None:
        if not self.equal:
            return
        try:
            self.equal = next(self.frames) == record
        except (StopIteration, LabelsStreamError):
            self.equal = False

    def close(self) -> None:
        """Read the rest of labels.json: equal only if no frame is left and the header is
        the manifest."""
        try:
            if self.equal:
                next(self.frames)
                self.equal = False  # a frame more than the journal holds
        except StopIteration:
            self.sha256 = self.digest.hexdigest()
            self.equal = not header_differences(self.labels.header, self.manifest)
        except LabelsStreamError:
            self.equal = False
        finally:
            self.frames.close()


def journal_pass(
    root: Path, manifest: dict, checks: RecordChecks, compare: bool
) -> tuple[JournalSpans, _InStep | None]:
    """Feed every journal record to ``checks``, in file order; with ``compare``, read
    labels.json in step with them.

    Raises SatsightError (from ``iter_journal``) at a line that is not a frame record.
    """
    spans = JournalSpans()
    in_step = _InStep(root / LABELS_NAME, manifest) if compare else None
    try:
        for record, offset, length in iter_journal(root):
            spans.add(record.get("frame_index"), offset, length)
            checks.add(record)
            if in_step is not None:
                in_step.feed(record)
    finally:
        if in_step is not None:
            in_step.close()
    return spans, in_step


def committed_count(root: Path, frame_count, findings: Findings) -> int:
    """The number of frames the journal holds (distinct frame indices); 0 and a problem
    when a line is not a frame record."""
    seen = bytearray(frame_count if is_count(frame_count) else 0)
    others: set[str] = set()
    try:
        for record, _, _ in iter_journal(root):
            index = record.get("frame_index")
            if is_int(index) and 0 <= index < len(seen):
                seen[index] = 1
            else:
                others.add(_key(index))
    except SatsightError as error:
        findings.add(
            "journal", f"expected one frame record per line, found: {error}", file=JOURNAL_NAME
        )
        return 0
    return seen.count(1) + len(others)
