"""A dataset's manifest, the scenario's fingerprint, and the closing of a finished dataset.

The manifest (``manifest.json``) is written before the first frame: it says what the
dataset is (everything ``labels.json`` holds except the frames). ``finalize_dataset``
closes a dataset whose frames are all committed: journal sorted, ``labels.json``, the
contact sheet, and ``complete.json`` last.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Iterator
from pathlib import Path

from satsight.dataset.contact_sheet import write_dataset_contact_sheet
from satsight.dataset.journal import (
    JOURNAL_NAME,
    sorted_journal_frames,
    write_bytes_atomic,
    write_lines_atomic,
)
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


def labels_lines(manifest: dict, journal_lines: Iterable[bytes]) -> Iterator[bytes]:
    """labels.json, piece by piece: the manifest (indented) with a ``frames`` list holding
    each frame's journal line as it is, one frame per line.

    The records are not parsed or encoded again: closing a 10^6-frame dataset costs a copy
    of its journal, not 10^6 passes of the (slow, pure-Python) indenting JSON encoder.
    """
    head = json.dumps(manifest, indent=1, allow_nan=False)
    yield (head[:-2] + ',\n "frames": [').encode("utf-8")
    separator = b"\n"
    for line in journal_lines:
        yield separator + b"  " + line.rstrip(b"\n")
        separator = b",\n"
    yield b"\n ]\n}\n" if separator == b",\n" else b"]\n}\n"


def finalize_dataset(root: Path, manifest: dict, journal_lines: Iterable[bytes]) -> None:
    """Close a dataset whose frames are all committed: the journal rewritten with
    ``journal_lines`` (every frame's line, in frame order), labels.json, the contact sheet
    (if the outputs have images and the scenario asks for it), and complete.json last.

    Records stream from file to file; memory does not grow with the frame count.
    """
    root = Path(root)
    journal_sha256 = write_lines_atomic(root / JOURNAL_NAME, journal_lines)
    frames = sorted_journal_frames(root)
    labels_sha256 = write_lines_atomic(
        root / LABELS_NAME, labels_lines(manifest, frames.raw_lines())
    )
    if manifest["outputs"]["contact_sheet"]:
        write_dataset_contact_sheet(root, manifest, frames)
    complete = {
        "frame_count": len(frames),
        "shard": manifest.get("shard"),
        "labels_sha256": labels_sha256,
        "journal_sha256": journal_sha256,
    }
    write_bytes_atomic(root / COMPLETE_NAME, json_bytes(complete))
