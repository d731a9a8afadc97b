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

import os
from pathlib import Path

import numpy as np

from satsight.dataset.frame_checks import TargetPoints
from satsight.dataset.journal import JOURNAL_NAME, file_checksum
from satsight.dataset.journal_pass import committed_count, journal_pass, scan_journal
from satsight.dataset.labels_pass import check_differing_labels, labels_pass
from satsight.dataset.problems import Findings
from satsight.dataset.reader import (
    COMPLETE_NAME,
    DATASET_VERSION,
    LABELS_NAME,
    MANIFEST_NAME,
    is_dataset,
    open_dataset,
    read_json,
)
from satsight.dataset.record_checks import (
    ProgressCallback,
    RecordChecks,
    expected_indices,
    is_count,
)
from satsight.dataset.validation_report import ValidationReport
from satsight.errors import SatsightError


def _sha256_of(path: Path) -> str | None:
    try:
        return file_checksum(path)["sha256"]
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
        done = committed_count(root, frame_count, head)
        head.add(
            "complete",
            f"expected {COMPLETE_NAME}, found none: an incomplete dataset "
            f"({done} of {frame_count} frames committed); finish it with 'satsight "
            f"generate SCENARIO --out {root} --resume', or check the committed frames "
            "with --allow-incomplete",
            file=COMPLETE_NAME,
        )
        return ValidationReport(root, False, frame_count, 0, head)
    count = len(expected_indices(manifest, frame_count)) if is_count(frame_count) else None
    keypoint_findings = Findings()
    keypoints = _target_points(manifest, keypoint_findings)
    threads = workers or min(4, os.cpu_count() or 1)

    def record_checks(record_file: str, total: int) -> RecordChecks:
        return RecordChecks(
            root, manifest, complete, record_file, keypoints, hashes, threads, on_frame_done,
            total,
        )  # fmt: skip

    journal_sha, journal_lines = scan_journal(root / JOURNAL_NAME)
    summary, labels_findings = Findings(), Findings()
    checks: RecordChecks | None = None
    labels_checks: RecordChecks | None = None  # labels.json's frames, where they differ
    journal_state = "missing"
    if journal_sha is not None:
        checks = record_checks(LABELS_NAME if complete else JOURNAL_NAME, journal_lines)
        try:
            spans, in_step = journal_pass(root, manifest, checks, compare=complete)
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
                labels_checks = RecordChecks(
                    root, manifest, complete, LABELS_NAME, keypoints, hashes, threads, None, 0
                )
                labels_checks = check_differing_labels(
                    root, manifest, spans, checks, labels_checks, labels_findings
                )
        else:
            checks = record_checks(LABELS_NAME, count or 0)
            try:
                readable = labels_pass(
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
