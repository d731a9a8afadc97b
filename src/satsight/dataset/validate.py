"""``satsight validate``: check a dataset folder against docs/dataset_format.md.

Every problem is collected (none stops the others) and names the frame and the file it
concerns, what was expected and what came. The dataset is only read, never written.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.dataset.frame_checks import FrameCheck
from satsight.dataset.journal import JOURNAL_NAME, read_journal
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


@dataclass(frozen=True)
class ValidationReport:
    """What ``validate_dataset`` found.

    root: the dataset folder. complete: complete.json present. frame_count: the manifest's
    frame count. frames_checked: frame records whose files and labels were checked.
    findings: the problems, and how many items each check looked at.
    """

    root: Path
    complete: bool
    frame_count: int
    frames_checked: int
    findings: Findings

    @property
    def ok(self) -> bool:
        """No problem found."""
        return not self.findings.problems


def _sha256_of(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _read_manifest(root: Path) -> dict:
    """The manifest of a dataset folder; a SatsightError when ``root`` is not one."""
    if not root.is_dir():
        raise SatsightError(f"dataset folder not found: {root}")
    if not is_dataset(root) or read_json(root / MANIFEST_NAME).get("version") != DATASET_VERSION:
        open_dataset(root, require_complete=False)  # raises the reader's explanation
        raise SatsightError(f"{root} is not a satsight dataset")
    return read_json(root / MANIFEST_NAME)


def _check_summary(root: Path, frame_count: int | None, findings: Findings) -> None:
    """complete.json: its frame count (the frames this folder holds: all of the manifest's,
    or its shard's) and the SHA-256 of labels.json and journal.jsonl."""
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
        recorded, actual = summary.get(key), _sha256_of(root / name)
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
    leftovers = sorted(p for p in root.rglob(".*.tmp-*") if p.is_file())
    for path in leftovers:
        findings.add(
            "complete",
            "expected no temporary files in a complete dataset, found this one",
            file=str(path.relative_to(root)),
        )


def _check_labels(
    root: Path, manifest: dict, journal: list[dict] | None, findings: Findings
) -> list | None:
    """labels.json: header equal to the manifest, frames equal to the journal records.

    Returns labels.json's frames (None when it cannot be read).
    """
    findings.ran("manifest")
    try:
        labels = read_json(root / LABELS_NAME)
        frames = labels.pop("frames")
        if not isinstance(frames, list):
            raise SatsightError(f"frames is a {type(frames).__name__}")
    except (SatsightError, KeyError) as error:
        findings.add("manifest", f"expected a frames list, found: {error}", file=LABELS_NAME)
        return None
    differ = sorted(k for k in set(labels) | set(manifest) if labels.get(k) != manifest.get(k))
    if differ:
        findings.add(
            "manifest",
            f"expected the header equal to {MANIFEST_NAME}, found other "
            f"values of {', '.join(differ)}",
            file=LABELS_NAME,
        )
    if journal is None:
        return frames
    findings.ran("journal", len(frames))
    by_index = {r.get("frame_index"): r for r in journal}
    for frame in frames:
        index = frame.get("frame_index") if isinstance(frame, dict) else None
        record = by_index.pop(index, None)
        if record is None:
            findings.add(
                "journal",
                f"expected a {JOURNAL_NAME} record of this frame, found none",
                index,
                LABELS_NAME,
            )
        elif record != frame:
            keys = sorted(k for k in set(record) | set(frame) if record.get(k) != frame.get(k))
            findings.add(
                "journal",
                f"expected the {JOURNAL_NAME} record, found other values of {', '.join(keys)}",
                index,
                LABELS_NAME,
            )
    for index in sorted(by_index, key=str):
        findings.add(
            "journal",
            f"expected this {JOURNAL_NAME} record in {LABELS_NAME}, found none",
            index,
            JOURNAL_NAME,
        )
    return frames


def _is_count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def expected_indices(manifest: dict, frame_count: int) -> set[int]:
    """The frame indices a complete dataset holds: all, or its shard's (``"K/N"``)."""
    shard = manifest.get("shard")
    if isinstance(shard, str) and "/" in shard:
        k, n = (int(v) for v in shard.split("/"))
        return {i for i in range(frame_count) if i % n == k - 1}
    return set(range(frame_count))


def _check_indices(
    frames: list, manifest: dict, complete: bool, record_file: str, findings: Findings
) -> None:
    """Frame indices 0 .. n-1, each once, in order (only committed ones when incomplete)."""
    findings.ran("indices")
    frame_count = manifest.get("frame_count")
    if not _is_count(frame_count):
        findings.add(
            "indices",
            f"expected frame_count a whole number, found {frame_count!r}",
            file=MANIFEST_NAME,
        )
        return
    expected = expected_indices(manifest, frame_count)
    seen: set[int] = set()
    previous = -1
    for frame in frames:
        index = frame.get("frame_index") if isinstance(frame, dict) else None
        if not isinstance(index, int) or isinstance(index, bool) or index not in expected:
            findings.add(
                "indices",
                f"expected a frame_index in 0 .. {frame_count - 1}, found {index!r}",
                file=record_file,
            )
            continue
        if index in seen:
            findings.add(
                "indices", "expected each frame once, found this one again", index, record_file
            )
        elif index < previous and complete:
            findings.add(
                "indices",
                f"expected frames sorted by frame_index, found {index} after {previous}",
                index,
                record_file,
            )
        seen.add(index)
        previous = max(previous, index)
        plan_indices = manifest.get("plan_indices")
        if isinstance(plan_indices, list) and index < len(plan_indices):
            if frame.get("plan_index") != plan_indices[index]:
                findings.add(
                    "indices",
                    f"expected plan_index {plan_indices[index]} (manifest plan_indices), "
                    f"found {frame.get('plan_index')!r}",
                    index,
                    record_file,
                )
    missing = sorted(expected - seen)
    if complete and missing:
        shown = ", ".join(map(str, missing[:10])) + (", ..." if len(missing) > 10 else "")
        findings.add(
            "indices",
            f"expected {len(expected)} frames (manifest frame_count "
            f"{frame_count}), found {len(seen)}; missing {shown}",
            file=record_file,
        )


def _keypoints_body_m(manifest: dict, findings: Findings) -> np.ndarray | None:
    try:
        points = np.array(manifest["target"]["keypoints_body_m"], dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"shape {points.shape}")
        return points
    except (KeyError, TypeError, ValueError) as error:
        findings.add(
            "pose",
            f"expected target.keypoints_body_m (N x 3), found {error!r}; keypoints not checked",
            file=MANIFEST_NAME,
        )
        return None


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

    Raises SatsightError when ``root`` is not a dataset folder at all.
    """
    root = Path(root)
    manifest = _read_manifest(root)
    frame_count = manifest.get("frame_count")
    findings = Findings()
    complete = (root / COMPLETE_NAME).is_file()
    findings.ran("complete")
    try:
        journal = read_journal(root)
    except SatsightError as error:
        findings.add(
            "journal", f"expected one frame record per line, found: {error}", file=JOURNAL_NAME
        )
        journal = None
    if not complete and not allow_incomplete:
        done = len({r.get("frame_index") for r in journal or []})
        findings.add(
            "complete",
            f"expected {COMPLETE_NAME}, found none: an incomplete dataset "
            f"({done} of {frame_count} frames committed); finish it with 'satsight "
            f"generate SCENARIO --out {root} --resume', or check the committed frames "
            "with --allow-incomplete",
            file=COMPLETE_NAME,
        )
        return ValidationReport(root, False, frame_count, 0, findings)
    frames: list | None = None
    if complete:
        count = len(expected_indices(manifest, frame_count)) if _is_count(frame_count) else None
        _check_summary(root, count, findings)
        frames = _check_labels(root, manifest, journal, findings)
    record_file = LABELS_NAME if frames is not None else JOURNAL_NAME
    if frames is None:
        frames = journal or []
    _check_indices(frames, manifest, complete, record_file, findings)
    keypoints = _keypoints_body_m(manifest, findings)
    records = [f for f in frames if isinstance(f, dict)]

    def check(frame: dict) -> Findings:
        try:
            return FrameCheck(root, frame, keypoints, record_file, hashes).run()
        except Exception as error:  # a record of an unexpected form: a problem, not a crash
            found = Findings()
            found.add(
                "files",
                f"expected a frame record as docs/dataset_format.md describes, found one "
                f"that cannot be checked ({type(error).__name__}: {error})",
                frame.get("frame_index"),
                record_file,
            )
            return found

    threads = workers or min(4, os.cpu_count() or 1)
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for done, result in enumerate(pool.map(check, records), start=1):
            findings.extend(result)
            if on_frame_done is not None:
                on_frame_done(done, len(records))
    return ValidationReport(root, complete, frame_count, len(records), findings)


def summary_table(report: ValidationReport):
    """A rich table: each check, what it looked at and the problems it found."""
    from rich.table import Table

    state = "complete" if report.complete else "incomplete"
    table = Table(
        title=f"{report.root}: {state}, {report.frames_checked} of {report.frame_count} "
        f"frames checked, {len(report.findings.problems)} problem(s)"
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
