"""``satsight validate``: check a dataset folder against docs/dataset_format.md.

Every problem is collected (none stops the others) and names the frame and the file it
concerns, what was expected and what came. The dataset is only read, never written.

Memory does not grow with the frame count beyond a few bytes per frame, so that a dataset
of 10^6 frames (a journal of several GB) is checked on a small machine:

- the frame records are read from the journal one at a time and checked on a few threads,
  with a bounded number of frames in flight;
- labels.json is parsed as a stream (``LabelsStream``) in step with the journal, each of
  its frames compared with the journal record at the same place, and hashed on the way;
  only when they differ is it read again, to match its frames with the journal's by frame
  index and name each frame that differs;
- frame indices are tracked in a byte per frame, journal lines in three integers each;
- problems are counted per check, and the first ``MAX_KEPT_PROBLEMS`` kept in full.
"""

from __future__ import annotations

import hashlib
import json
import os
from array import array
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from satsight.dataset.frame_checks import FrameCheck, TargetPoints
from satsight.dataset.journal import JOURNAL_NAME, file_checksum, iter_journal
from satsight.dataset.labels_stream import LabelsStream, LabelsStreamError
from satsight.dataset.problems import CHECKS, Findings
from satsight.dataset.reader import (
    COMPLETE_NAME,
    DATASET_VERSION,
    LABELS_NAME,
    MANIFEST_NAME,
    is_dataset,
    open_dataset,
    read_json,
)
from satsight.errors import SatsightError

ProgressCallback = Callable[[int, int], None]
_READ_BYTES = 1 << 20
_INT64 = (-(1 << 63), 1 << 63)


@dataclass(frozen=True)
class ValidationReport:
    """What ``validate_dataset`` found.

    root: the dataset folder. complete: complete.json present. frame_count: the manifest's
    frame count. frames_checked: frame records whose files and labels were checked.
    findings: the problems (the first ``MAX_KEPT_PROBLEMS`` in full, all counted), and how
    many items each check looked at.
    """

    root: Path
    complete: bool
    frame_count: int
    frames_checked: int
    findings: Findings

    @property
    def ok(self) -> bool:
        """No problem found."""
        return self.findings.total == 0


def _sha256_of(path: Path) -> str | None:
    try:
        return file_checksum(path)["sha256"]
    except OSError:
        return None


def _scan_journal(path: Path) -> tuple[str | None, int]:
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


def _read_manifest(root: Path) -> dict:
    """The manifest of a dataset folder; a SatsightError when ``root`` is not one."""
    if not root.is_dir():
        raise SatsightError(f"dataset folder not found: {root}")
    if not is_dataset(root) or read_json(root / MANIFEST_NAME).get("version") != DATASET_VERSION:
        open_dataset(root, require_complete=False)  # raises the reader's explanation
        raise SatsightError(f"{root} is not a satsight dataset")
    return read_json(root / MANIFEST_NAME)


def _check_summary(
    root: Path, frame_count: int | None, digests: dict[str, str | None], findings: Findings
) -> None:
    """complete.json: its frame count (the frames this folder holds: all of the manifest's,
    or its shard's) and the SHA-256 of labels.json and journal.jsonl (``digests``: file
    name -> its SHA-256, None when missing)."""
    try:
        summary = read_json(root / COMPLETE_NAME)
    except SatsightError as error:
        findings.add("complete", f"expected a JSON object, found: {error}", file=COMPLETE_NAME)
        return
    if frame_count is not None and summary.get("frame_count") != frame_count:
        findings.add(
            "complete",
            f"expected frame_count {frame_count} (from {MANIFEST_NAME}), found "
            f"{summary.get('frame_count')!r}",
            file=COMPLETE_NAME,
        )
    for name, key in ((LABELS_NAME, "labels_sha256"), (JOURNAL_NAME, "journal_sha256")):
        recorded, actual = summary.get(key), digests[name]
        if recorded is None:
            findings.add("complete", f"expected {key}, found none", file=COMPLETE_NAME)
        elif actual is None:
            findings.add(
                "complete",
                f"expected {name} (its SHA-256 is in {COMPLETE_NAME}), found none (missing)",
                file=name,
            )
        elif recorded != actual:
            findings.add(
                "complete",
                f"expected SHA-256 {recorded} ({COMPLETE_NAME}), found "
                f"{actual}: {name} changed after the dataset was completed",
                file=name,
            )
    for path in sorted(p for p in root.rglob(".*.tmp-*") if p.is_file()):
        findings.add(
            "complete",
            "expected no temporary files in a complete dataset, found this one",
            file=str(path.relative_to(root)),
        )


def _is_count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _key(value) -> str:
    """A frame index that is not an integer, as a hashable key (JSON text)."""
    return json.dumps(value, sort_keys=True)


def expected_indices(manifest: dict, frame_count: int) -> range:
    """The frame indices a complete dataset holds: all, or its shard's (``"K/N"``)."""
    shard = manifest.get("shard")
    if isinstance(shard, str) and "/" in shard:
        k, n = (int(v) for v in shard.split("/"))
        return range(k - 1, frame_count, n) if 1 <= k <= n else range(0)
    return range(frame_count)


class _IndexCheck:
    """Frame indices 0 .. n-1, each once, in order (only committed ones when incomplete),
    checked as the records stream past; one byte per frame remembers which were seen."""

    def __init__(self, manifest: dict, complete: bool, record_file: str):
        self.findings = Findings()
        self.findings.ran("indices")
        self.complete, self.record_file = complete, record_file
        self.frame_count = manifest.get("frame_count")
        self.valid = _is_count(self.frame_count)
        if not self.valid:
            self.findings.add(
                "indices",
                f"expected frame_count a whole number, found {self.frame_count!r}",
                file=MANIFEST_NAME,
            )
            return
        self.expected = expected_indices(manifest, self.frame_count)
        self.seen = bytearray(self.frame_count)
        self.previous = -1
        plan = manifest.get("plan_indices")
        self.plan_indices = plan if isinstance(plan, list) else None

    def add(self, message: str, index=None) -> None:
        self.findings.add("indices", message, index, self.record_file)

    def see(self, frame) -> None:
        """Check the next record's frame index and plan index."""
        if not self.valid:
            return
        index = frame.get("frame_index") if isinstance(frame, dict) else None
        if not _is_int(index) or index not in self.expected:
            self.add(f"expected a frame_index in 0 .. {self.frame_count - 1}, found {index!r}")
            return
        if self.seen[index]:
            self.add("expected each frame once, found this one again", index)
        elif index < self.previous and self.complete:
            self.add(
                f"expected frames sorted by frame_index, found {index} after {self.previous}",
                index,
            )
        self.seen[index] = 1
        self.previous = max(self.previous, index)
        plan = self.plan_indices
        if plan is not None and index < len(plan) and frame.get("plan_index") != plan[index]:
            self.add(
                f"expected plan_index {plan[index]} (manifest plan_indices), "
                f"found {frame.get('plan_index')!r}",
                index,
            )

    def finish(self) -> None:
        """Report the missing frames of a complete dataset."""
        if not (self.valid and self.complete):
            return
        expected = self.expected
        seen = np.frombuffer(self.seen, dtype=np.uint8)[
            expected.start : expected.stop : expected.step
        ]
        missing = np.flatnonzero(seen == 0)
        if missing.size:
            first = (missing[:10] * expected.step + expected.start).tolist()
            shown = ", ".join(map(str, first)) + (", ..." if missing.size > 10 else "")
            self.add(
                f"expected {len(expected)} frames (manifest frame_count "
                f"{self.frame_count}), found {int(np.count_nonzero(seen))}; missing {shown}"
            )


def _has_files(frame: dict) -> bool:
    crop = frame.get("crop")
    return bool(frame.get("files")) or (isinstance(crop, dict) and bool(crop.get("files")))


class _RecordChecks:
    """The checks of each frame record, fed one at a time (``add``): its indices at once,
    its labels and files on a thread pool with at most ``2 * threads`` frames in flight,
    their findings taken in order.

    record_file: where problems of a record are said to lie. total: the frames expected,
    for ``on_frame_done(done, total)``.
    """

    def __init__(
        self,
        root: Path,
        manifest: dict,
        complete: bool,
        record_file: str,
        keypoints: TargetPoints,
        hashes: bool,
        threads: int,
        on_frame_done: ProgressCallback | None,
        total: int,
    ):
        self.root, self.record_file = root, record_file
        self.keypoints, self.hashes = keypoints, hashes
        self.indices = _IndexCheck(manifest, complete, record_file)
        self.frames = Findings()
        self.records = 0
        self.checked = 0
        self.on_frame_done, self.total = on_frame_done, total
        self.window = 2 * threads
        self.pending: deque = deque()
        self.pool = ThreadPoolExecutor(max_workers=threads)

    def _check(self, frame: dict) -> Findings:
        try:
            return FrameCheck(self.root, frame, self.keypoints, self.record_file, self.hashes).run()
        except Exception as error:  # a record of an unexpected form: a problem, not a crash
            found = Findings()
            found.add(
                "files",
                f"expected a frame record as docs/dataset_format.md describes, found one "
                f"that cannot be checked ({type(error).__name__}: {error})",
                frame.get("frame_index"),
                self.record_file,
            )
            return found

    def add(self, frame, check_frame: bool = True) -> None:
        """Check a record's indices, and with ``check_frame`` its labels and files."""
        self.records += 1
        self.indices.see(frame)
        if not (check_frame and isinstance(frame, dict)):
            return
        if _has_files(frame):
            self.pending.append(self.pool.submit(self._check, frame))
        else:  # nothing to read: a thread would only add the cost of handing it over
            done: Future = Future()
            done.set_result(self._check(frame))
            self.pending.append(done)
        while len(self.pending) >= self.window:
            self._collect()

    def _collect(self) -> None:
        self.frames.extend(self.pending.popleft().result())
        self.checked += 1
        if self.on_frame_done is not None:
            self.on_frame_done(self.checked, max(self.total, self.checked))

    def finish(self) -> _RecordChecks:
        """Wait for the frames in flight; the missing indices."""
        while self.pending:
            self._collect()
        self.pool.shutdown()
        self.indices.finish()
        return self

    def abort(self) -> None:
        """Drop the frames in flight (their records are not to be checked after all)."""
        for future in self.pending:
            future.cancel()
        self.pool.shutdown(wait=True, cancel_futures=True)

    def relabel(self, old: str, new: str) -> None:
        """Say ``new`` instead of ``old`` as the record file of the problems kept."""
        for findings in (self.indices.findings, self.frames):
            findings.problems = [
                replace(p, file=new) if p.file == old else p for p in findings.problems
            ]


class _JournalSpans:
    """Where each journal line lies (byte offset and length), by frame index: three
    integers per line. ``freeze`` before ``take``."""

    def __init__(self):
        self._index, self._offset, self._length = array("q"), array("q"), array("q")
        self._other: dict[str, tuple[int, int]] = {}  # frame indices that are not integers
        self._other_taken: set[str] = set()

    def add(self, frame_index, offset: int, length: int) -> None:
        if _is_int(frame_index) and _INT64[0] <= frame_index < _INT64[1]:
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
        if _is_int(frame_index) and _INT64[0] <= frame_index < _INT64[1]:
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
            self.equal = not _header_differences(self.labels.header, self.manifest)
        except LabelsStreamError:
            self.equal = False
        finally:
            self.frames.close()


def _journal_pass(
    root: Path, manifest: dict, checks: _RecordChecks, compare: bool
) -> tuple[_JournalSpans, _InStep | None]:
    """Feed every journal record to ``checks``, in file order; with ``compare``, read
    labels.json in step with them.

    Raises SatsightError (from ``iter_journal``) at a line that is not a frame record.
    """
    spans = _JournalSpans()
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


def _header_differences(header: dict, manifest: dict) -> list[str]:
    """The keys whose values differ between labels.json's header and the manifest."""
    return sorted(k for k in set(header) | set(manifest) if header.get(k) != manifest.get(k))


def _check_header(header: dict, manifest: dict, findings: Findings) -> None:
    differ = _header_differences(header, manifest)
    if differ:
        findings.add(
            "manifest",
            f"expected the header equal to {MANIFEST_NAME}, found other "
            f"values of {', '.join(differ)}",
            file=LABELS_NAME,
        )


def _compare_labels(
    root: Path,
    manifest: dict,
    spans: _JournalSpans,
    journal_records: int,
    checks: _RecordChecks,
    findings: Findings,
) -> bool | None:
    """labels.json, parsed as a stream: its header against the manifest, its frames
    against the journal records at ``spans``, and the reverse. Its frames' indices go to
    ``checks``, and the frames that differ from their journal record (or have none) are
    checked in full there.

    Returns whether labels.json holds other values than the manifest and the
    ``journal_records`` lines of the journal; None when it cannot be read (``findings``
    then holds that problem and no other).
    """
    findings.ran("manifest")
    differences = Findings()
    labels = LabelsStream(root / LABELS_NAME)
    count = 0
    try:
        with open(root / JOURNAL_NAME, "rb") as journal:
            for frame in labels.frames():
                count += 1
                index = frame.get("frame_index") if isinstance(frame, dict) else None
                span = spans.take(index)
                if span is None:
                    differences.add(
                        "journal",
                        f"expected a {JOURNAL_NAME} record of this frame, found none",
                        index,
                        LABELS_NAME,
                    )
                    checks.add(frame)
                    continue
                journal.seek(span[0])
                record = json.loads(journal.read(span[1]))
                checks.add(frame, check_frame=record != frame)
                if record != frame:
                    keys = sorted(
                        k for k in set(record) | set(frame) if record.get(k) != frame.get(k)
                    )
                    differences.add(
                        "journal",
                        f"expected the {JOURNAL_NAME} record, found other values of "
                        f"{', '.join(keys)}",
                        index,
                        LABELS_NAME,
                    )
    except LabelsStreamError as error:
        findings.add("manifest", f"expected a frames list, found: {error}", file=LABELS_NAME)
        return None
    _check_header(labels.header, manifest, findings)
    findings.ran("journal", count)
    findings.extend(differences)
    for index in spans.untaken():
        findings.add(
            "journal",
            f"expected this {JOURNAL_NAME} record in {LABELS_NAME}, found none",
            index,
            JOURNAL_NAME,
        )
    return findings.total > 0 or count != journal_records


def _check_differing_labels(
    root: Path,
    manifest: dict,
    spans: _JournalSpans,
    checks: _RecordChecks,
    labels_checks: _RecordChecks,
    findings: Findings,
) -> _RecordChecks | None:
    """labels.json is not the journal, byte for byte and frame for frame: name its frames
    that differ (``_compare_labels``). When their values differ (or labels.json cannot be
    read), the problems of the journal's records (``checks``) are not all in labels.json:
    they are said to lie in the journal, and labels.json's own frames are checked in
    ``labels_checks``, which is returned (None when it has nothing to add)."""
    try:
        differs = _compare_labels(root, manifest, spans, checks.records, labels_checks, findings)
    except BaseException:
        labels_checks.abort()
        raise
    if differs is None or differs:
        checks.relabel(LABELS_NAME, JOURNAL_NAME)
    if not differs:
        labels_checks.abort()
        return None
    return labels_checks.finish()


def _labels_pass(
    root: Path, manifest: dict, checks: _RecordChecks, journal_missing: bool, findings: Findings
) -> bool:
    """Feed labels.json's frames to ``checks`` (the journal cannot be read); its header
    against the manifest; with ``journal_missing``, each frame lacks its journal record.

    Returns False when labels.json cannot be read; ``findings`` then holds that problem.
    """
    findings.ran("manifest")
    missing = Findings()
    labels = LabelsStream(root / LABELS_NAME)
    count = 0
    try:
        for frame in labels.frames():
            count += 1
            checks.add(frame)
            if journal_missing:
                missing.add(
                    "journal",
                    f"expected a {JOURNAL_NAME} record of this frame, found none",
                    frame.get("frame_index") if isinstance(frame, dict) else None,
                    LABELS_NAME,
                )
    except LabelsStreamError as error:
        findings.add("manifest", f"expected a frames list, found: {error}", file=LABELS_NAME)
        return False
    _check_header(labels.header, manifest, findings)
    if journal_missing:
        findings.ran("journal", count)
        findings.extend(missing)
    return True


def _committed_count(root: Path, frame_count, findings: Findings) -> int:
    """The number of frames the journal holds (distinct frame indices); 0 and a problem
    when a line is not a frame record."""
    seen = bytearray(frame_count if _is_count(frame_count) else 0)
    others: set[str] = set()
    try:
        for record, _, _ in iter_journal(root):
            index = record.get("frame_index")
            if _is_int(index) and 0 <= index < len(seen):
                seen[index] = 1
            else:
                others.add(_key(index))
    except SatsightError as error:
        findings.add(
            "journal", f"expected one frame record per line, found: {error}", file=JOURNAL_NAME
        )
        return 0
    return seen.count(1) + len(others)


def _points(manifest: dict, key: str, findings: Findings) -> np.ndarray | None:
    try:
        points = np.array(manifest["target"][key], dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"shape {points.shape}")
        return points
    except (KeyError, TypeError, ValueError) as error:
        findings.add(
            "pose",
            f"expected target.{key} (N x 3), found {error!r}; its labels not checked",
            file=MANIFEST_NAME,
        )
        return None


def _target_points(manifest: dict, findings: Findings) -> TargetPoints:
    """The manifest's keypoints and box points; a dataset without box_keypoints_body_m
    (written before it existed) labelled the box as its keypoints."""
    keypoints = _points(manifest, "keypoints_body_m", findings)
    if "box_keypoints_body_m" not in (manifest.get("target") or {}):
        return TargetPoints(keypoints, keypoints, box_is_keypoints=True)
    return TargetPoints(keypoints, _points(manifest, "box_keypoints_body_m", findings))


def validate_dataset(
    root: Path,
    hashes: bool = True,
    allow_incomplete: bool = False,
    on_frame_done: ProgressCallback | None = None,
    workers: int | None = None,
) -> ValidationReport:
    """Check the dataset in ``root`` and return every problem found.

    hashes: compare every file's SHA-256 with its frame's checksums (sizes are always
    compared). allow_incomplete: check the committed frames of a dataset without
    complete.json instead of reporting it as incomplete. on_frame_done(done, total): called
    after each frame. workers: threads checking frames (default: up to 4).

    The frame records checked are the journal's (labels.json must equal them: the
    ``journal`` check); problems in them are said to lie in labels.json when the dataset is
    complete and labels.json readable, else in journal.jsonl. When the journal cannot be
    read, labels.json's frames are checked instead. Memory stays bounded whatever the
    frame count (see the module docstring).

    Raises SatsightError when ``root`` is not a dataset folder at all.
    """
    root = Path(root)
    manifest = _read_manifest(root)
    frame_count = manifest.get("frame_count")
    complete = (root / COMPLETE_NAME).is_file()
    head = Findings()  # journal readable; complete.json present
    head.ran("complete")
    if not complete and not allow_incomplete:
        done = _committed_count(root, frame_count, head)
        head.add(
            "complete",
            f"expected {COMPLETE_NAME}, found none: an incomplete dataset "
            f"({done} of {frame_count} frames committed); finish it with 'satsight "
            f"generate SCENARIO --out {root} --resume', or check the committed frames "
            "with --allow-incomplete",
            file=COMPLETE_NAME,
        )
        return ValidationReport(root, False, frame_count, 0, head)
    count = len(expected_indices(manifest, frame_count)) if _is_count(frame_count) else None
    keypoint_findings = Findings()
    keypoints = _target_points(manifest, keypoint_findings)
    threads = workers or min(4, os.cpu_count() or 1)

    def record_checks(record_file: str, total: int) -> _RecordChecks:
        return _RecordChecks(
            root, manifest, complete, record_file, keypoints, hashes, threads, on_frame_done,
            total,
        )  # fmt: skip

    journal_sha, journal_lines = _scan_journal(root / JOURNAL_NAME)
    summary, labels_findings = Findings(), Findings()
    checks: _RecordChecks | None = None
    labels_checks: _RecordChecks | None = None  # labels.json's frames, where they differ
    journal_state = "missing"
    if journal_sha is not None:
        checks = record_checks(LABELS_NAME if complete else JOURNAL_NAME, journal_lines)
        try:
            spans, in_step = _journal_pass(root, manifest, checks, compare=complete)
            checks.finish()
            journal_state = "read"
        except SatsightError as error:  # a line that is not a frame record
            checks.abort()
            checks = None
            journal_state = "corrupt"
            head.add(
                "journal", f"expected one frame record per line, found: {error}", file=JOURNAL_NAME
            )
        except BaseException:
            checks.abort()
            raise
    if complete:
        if journal_state == "read":
            labels_sha = in_step.sha256 or _sha256_of(root / LABELS_NAME)
            if in_step.equal:  # labels.json is the manifest and the journal's records
                labels_findings.ran("manifest")
                labels_findings.ran("journal", checks.records)
            else:
                spans.freeze()
                labels_checks = _RecordChecks(
                    root, manifest, complete, LABELS_NAME, keypoints, hashes, threads, None, 0
                )
                labels_checks = _check_differing_labels(
                    root, manifest, spans, checks, labels_checks, labels_findings
                )
        else:
            checks = record_checks(LABELS_NAME, count or 0)
            try:
                readable = _labels_pass(
                    root, manifest, checks, journal_state == "missing", labels_findings
                )
            except BaseException:
                checks.abort()
                raise
            if readable:
                checks.finish()
            else:
                checks.abort()
                checks = None
            labels_sha = _sha256_of(root / LABELS_NAME)
        digests = {LABELS_NAME: labels_sha, JOURNAL_NAME: journal_sha}
        _check_summary(root, count, digests, summary)
    if checks is None:  # no records can be read: the indices alone
        checks = record_checks(JOURNAL_NAME, 0).finish()
    findings = Findings()
    parts = [head, summary, labels_findings]
    parts += [labels_checks.indices.findings] if labels_checks is not None else []
    parts += [checks.indices.findings, keypoint_findings]
    parts += [labels_checks.frames] if labels_checks is not None else []
    for part in [*parts, checks.frames]:
        findings.extend(part)
    return ValidationReport(root, complete, frame_count, checks.checked, findings)


def omitted_line(report: ValidationReport) -> str | None:
    """A line saying how many problems were found beyond those kept; None when none were."""
    omitted = report.findings.omitted
    if not omitted:
        return None
    return (
        f"... and {omitted} more problem(s), not listed: the first {report.findings.limit} "
        "are kept in full, the table below counts them all"
    )


def summary_table(report: ValidationReport):
    """A rich table: each check, what it looked at and the problems it found."""
    from rich.table import Table

    state = "complete" if report.complete else "incomplete"
    table = Table(
        title=f"{report.root}: {state}, {report.frames_checked} of {report.frame_count} "
        f"frames checked, {report.findings.total} problem(s)"
    )
    for column, justify in (
        ("check", "left"),
        ("what", "left"),
        ("items", "right"),
        ("problems", "right"),
    ):
        table.add_column(column, justify=justify)
    for name, (checked, found) in report.findings.counts().items():
        style = "red" if found else ("green" if checked else "dim")
        table.add_row(name, CHECKS[name], str(checked), str(found), style=style)
    return table
