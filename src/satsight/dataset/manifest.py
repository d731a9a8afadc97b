"""A dataset's manifest, the scenario's fingerprint, and the closing of a finished dataset.

The manifest (``manifest.json``) is written before the first frame: it says what the
dataset is (everything ``labels.json`` holds except the frames). ``finalize_dataset``
closes a dataset whose frames are all committed: journal sorted, ``labels.json``, the
contact sheet, and ``complete.json`` last.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from satsight.dataset.contact_sheet import write_dataset_contact_sheet
from satsight.dataset.journal import write_bytes_atomic, write_sorted_journal
from satsight.dataset.reader import (
    COMPLETE_NAME,
    DATASET_FORMAT,
    DATASET_VERSION,
    LABELS_NAME,
    MANIFEST_NAME,
)


def json_bytes(document: dict) -> bytes:
    """Indented UTF-8 JSON with a final newline (the dataset's JSON files)."""
    return (json.dumps(document, indent=1, allow_nan=False) + "\n").encode("utf-8")


def scenario_sha256(scenario_json: dict) -> str:
    """SHA-256 of a validated scenario's canonical JSON (sorted keys, no spaces).

    Equal scenarios, defaults included, give equal hashes whatever the YAML looked like.
    """
    canonical = json.dumps(scenario_json, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def manifest_document(header: dict) -> dict:
    """The manifest: format and version first, then the dataset's header."""
    return {"format": DATASET_FORMAT, "version": DATASET_VERSION, **header}


def write_manifest(root: Path, manifest: dict) -> None:
    write_bytes_atomic(Path(root) / MANIFEST_NAME, json_bytes(manifest))


def finalize_dataset(root: Path, manifest: dict, records: list[dict]) -> None:
    """Close a dataset whose frames are all in ``records``: sorted journal, labels.json,
    contact sheet (if the outputs have images and the scenario asks for it), and
    complete.json last."""
    root = Path(root)
    records = sorted(records, key=lambda r: r["frame_index"])
    journal = write_sorted_journal(root, records)
    labels = json_bytes({**manifest, "frames": records})
    write_bytes_atomic(root / LABELS_NAME, labels)
    if manifest["outputs"]["contact_sheet"]:
        write_dataset_contact_sheet(root, manifest, records)
    complete = {
        "frame_count": len(records),
        "shard": manifest.get("shard"),
        "labels_sha256": hashlib.sha256(labels).hexdigest(),
        "journal_sha256": hashlib.sha256(journal).hexdigest(),
    }
    write_bytes_atomic(root / COMPLETE_NAME, json_bytes(complete))
