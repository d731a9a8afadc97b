"""Reading a dataset folder: its manifest, its frame records and the paths of their files.

Every tool that reads a dataset (``validate``, ``stats``, the exporters, ``merge``) opens it
here, so that none of them mistakes an incomplete dataset for a complete one.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from satsight.dataset.journal import journal_frames, sorted_journal_frames
from satsight.errors import SatsightError

MANIFEST_NAME = "manifest.json"
LABELS_NAME = "labels.json"
COMPLETE_NAME = "complete.json"
DATASET_FORMAT = "satsight-dataset"
DATASET_VERSION = 3


def read_json(path: Path) -> dict:
    """A JSON object from a file, or a SatsightError naming the file."""
    try:
        document = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SatsightError(f"{path} is missing") from None
    except (OSError, ValueError) as error:
        raise SatsightError(f"{path} is not readable JSON: {error}") from None
    if not isinstance(document, dict):
        raise SatsightError(f"{path} does not hold a JSON object")
    return document


def is_dataset(folder: Path) -> bool:
    """Whether ``folder`` holds a satsight dataset, complete or not (its manifest says so)."""
    try:
        manifest = read_json(Path(folder) / MANIFEST_NAME)
    except SatsightError:
        return False
    return manifest.get("format") == DATASET_FORMAT


@dataclass(frozen=True)
class Dataset:
    """An opened dataset folder.

    root: the folder. header: the manifest (labels.json without its frames). frames: the
    frame records, sorted by frame_index (see docs/dataset_format.md), read from the
    journal on demand (a sequence: index it or iterate it; a 10^6-frame dataset is not
    held in memory). complete: whether ``complete.json`` is present (every planned frame
    committed, labels.json written).
    """

    root: Path
    header: dict
    frames: Sequence[dict]
    complete: bool

    @property
    def frame_count(self) -> int:
        """Frames the dataset holds (or will hold, when incomplete)."""
        return int(self.header["frame_count"])

    def files(self, frame: dict, crop: bool = False) -> dict[str, str]:
        """Output name -> relative path of a frame's files (full frame, or its crop)."""
        if crop:
            return dict((frame.get("crop") or {}).get("files", {}))
        return dict(frame.get("files", {}))

    def path(self, frame: dict, key: str, crop: bool = False) -> Path | None:
        """Absolute path of one of a frame's files (e.g. ``dn_png16``), None if not written."""
        relative = self.files(frame, crop).get(key)
        return None if relative is None else self.root / relative


def open_dataset(root: Path, require_complete: bool = True) -> Dataset:
    """Open the dataset in ``root``.

    A complete dataset is read from labels.json. With ``require_complete=False`` an
    incomplete one is read from its manifest and journal (committed frames only).
    """
    root = Path(root)
    if not root.is_dir():
        raise SatsightError(f"dataset folder not found: {root}")
    if not (root / MANIFEST_NAME).is_file():
        if (root / LABELS_NAME).is_file():
            raise SatsightError(
                f"{root} holds a labels.json but no manifest.json: it was written by an "
                "older satsight (format version 2); regenerate it"
            )
        raise SatsightError(f"{root} is not a satsight dataset (no {MANIFEST_NAME})")
    manifest = read_json(root / MANIFEST_NAME)
    if manifest.get("format") != DATASET_FORMAT:
        raise SatsightError(f"{root / MANIFEST_NAME} is not a satsight dataset manifest")
    if manifest.get("version") != DATASET_VERSION:
        raise SatsightError(
            f"{root} is format version {manifest.get('version')}; this satsight reads "
            f"version {DATASET_VERSION}"
        )
    complete = (root / COMPLETE_NAME).is_file()
    if complete:
        # The closed journal holds one line per frame in frame order; it and labels.json
        # hold the same records (their hashes are in complete.json; validate compares).
        return Dataset(root, manifest, sorted_journal_frames(root), True)
    if require_complete:
        done = len(journal_frames(root))
        raise SatsightError(
            f"{root} is an incomplete dataset ({done} of {manifest.get('frame_count')} "
            "frames committed, no complete.json); finish it with 'satsight generate "
            f"SCENARIO --out {root} --resume'"
        )
    return Dataset(root, manifest, journal_frames(root), False)
