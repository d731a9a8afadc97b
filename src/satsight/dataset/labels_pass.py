"""The labels pass of ``satsight validate``: labels.json parsed as a stream, its header
against the manifest and its frames against the journal's records (matched by frame index
when they are not the journal, byte for byte), or checked on their own when the journal
cannot be read."""

from __future__ import annotations

import json
from pathlib import Path

from satsight.dataset.journal import JOURNAL_NAME
from satsight.dataset.journal_pass import JournalSpans, header_differences
from satsight.dataset.labels_stream import LabelsStream, LabelsStreamError
from satsight.dataset.problems import Findings
from satsight.dataset.reader import LABELS_NAME, MANIFEST_NAME
from satsight.dataset.record_checks import RecordChecks


def _check_header(header: dict, manifest: dict, findings: Findings) -> None:
    differ = header_differences(header, manifest)
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
    spans: JournalSpans,
    journal_records: int,
    checks: RecordChecks,
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


def check_differing_labels(
    root: Path,
    manifest: dict,
    spans: JournalSpans,
    checks: RecordChecks,
    labels_checks: RecordChecks,
    findings: Findings,
) -> RecordChecks | None:
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


def labels_pass(
    root: Path, manifest: dict, checks: RecordChecks, journal_missing: bool, findings: Findings
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
