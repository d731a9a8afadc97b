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

import numpy as np

from satsight.dataset.image_files import read_png
from satsight.dataset.journal import write_bytes_atomic, write_sorted_journal
from satsight.dataset.preview import crop_box_xyxy_px, thumbnail, write_contact_sheet
from satsight.dataset.reader import (
    COMPLETE_NAME,
    DATASET_FORMAT,
    DATASET_VERSION,
    LABELS_NAME,
    MANIFEST_NAME,
)

#: Frames shown on the contact sheet at most, spread evenly over the dataset: a sheet of
#: every frame grows without bound (72 frames made an unreadable 1260 x 11520 px image).
CONTACT_SHEET_MAX_FRAMES = 36


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


def _frame_thumbnail(root: Path, record: dict, bias_dn: float) -> np.ndarray | None:
    """A small grey image of the target from the frame's DN (or preview) file, or None.

    The DN image is shown above the detector's bias, scaled to its own maximum.
    """
    crop = record.get("crop") or {}
    for files, bbox in (
        (record.get("files") or {}, record.get("bbox_xyxy_px")),
        (crop.get("files") or {}, crop.get("bbox_xyxy_px")),
    ):
        for key in ("dn_png16", "preview_png8"):
            if key not in files:
                continue
            image = read_png(root / files[key]).astype(np.float32)
            if key == "dn_png16":
                image = np.clip(image - np.float32(bias_dn), 0.0, None)
            x0, y0, x1, y1 = crop_box_xyxy_px(bbox, image.shape)
            return thumbnail(image[y0:y1, x0:x1, None], max_side_px=256)[..., 0]
    return None


def contact_sheet_frames(count: int) -> list[int]:
    """Frame indices on the contact sheet: all, or an even spread of at most the maximum."""
    if count <= CONTACT_SHEET_MAX_FRAMES:
        return list(range(count))
    return sorted(
        set(np.rint(np.linspace(0, count - 1, CONTACT_SHEET_MAX_FRAMES)).astype(int).tolist())
    )


def write_dataset_contact_sheet(
    root: Path, records: list[dict], heading: str, bias_dn: float
) -> bool:
    """Thumbnails of up to ``CONTACT_SHEET_MAX_FRAMES`` frames; False when no file shows any."""
    thumbs, titles = [], []
    for index in contact_sheet_frames(len(records)):
        record = records[index]
        image = _frame_thumbnail(root, record, bias_dn)
        if image is None:
            return False
        plan = record.get("plan", {})
        flags = "" if plan.get("visible", True) else "  [fails visibility]"
        thumbs.append(image)
        titles.append(
            f"#{record['frame_index']}  {record['range_m'] / 1e3:.3g} km, "
            f"phase {record['phase_angle_deg']:.0f}°{flags}\n"
            f"{record['object_pixel_count']} px on target"
        )
    shown = f"{len(thumbs)} of {len(records)} frames" if len(thumbs) < len(records) else ""
    write_contact_sheet(
        root / "contact_sheet.png", thumbs, titles, heading + (f" ({shown})" if shown else "")
    )
    return True


def dataset_heading(manifest: dict) -> str:
    """The contact sheet's title: scenario, target, image size and focal length."""
    camera = manifest["camera"]
    width, height = camera["image_size_px"]
    return (
        f"{manifest['scenario']}: {manifest['target']['name']}, {width}x{height} px, "
        f"f = {camera['focal_length_m']:g} m"
    )


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
        bias_dn = manifest["sensor"]["detector"]["bias_dn"]
        write_dataset_contact_sheet(root, records, dataset_heading(manifest), bias_dn)
    complete = {
        "frame_count": len(records),
        "shard": manifest.get("shard"),
        "labels_sha256": hashlib.sha256(labels).hexdigest(),
        "journal_sha256": hashlib.sha256(journal).hexdigest(),
    }
    write_bytes_atomic(root / COMPLETE_NAME, json_bytes(complete))
