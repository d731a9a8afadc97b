"""The checks of a dataset's frame records as they stream past (``satsight validate``):
each record's frame index and plan index at once, its labels and files on a few threads,
with a bounded number of frames in flight; one byte per frame remembers which were seen."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from satsight.dataset.frame_checks import FrameCheck, TargetPoints
from satsight.dataset.problems import Findings
from satsight.dataset.reader import MANIFEST_NAME

#: on_frame_done(done, total): called after each frame record is checked.
ProgressCallback = Callable[[int, int], None]


def is_count(value) -> bool:
    """A whole number of things: an int (not a bool), 0 or more."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def is_int(value) -> bool:
    """An int that is not a bool (JSON true and false are not frame indices)."""
    return isinstance(value, int) and not isinstance(value, bool)


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
        self.valid = is_count(self.frame_count)
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
        if not is_int(index) or index not in self.expected:
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


class RecordChecks:
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

    def finish(self) -> RecordChecks:
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
