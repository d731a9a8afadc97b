"""The dataset's contact sheet: thumbnails of up to 36 frames spread over the dataset.

A frame's thumbnail is the target's neighbourhood in its DN image (above the bias; or its
8-bit preview, or its crop's, whichever the outputs hold), scaled to its own maximum with
display gamma 2.2: the sheet keeps this stretch of its own, whatever the previews' stretch
(``outputs.preview_stretch``), because it shows the target, each frame at its best, in
thumbnails whose box average dilutes the stars anyway. The
frames on the sheet are known before the run, so their thumbnails are kept while they are
rendered (in ``.thumbnails/`` inside the dataset, removed when the sheet is drawn) and the
sheet costs no decoding of full frames; a thumbnail that is missing there (a resumed run)
is made from the frame's file, with the same result.
"""

from __future__ import annotations

import io
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from satsight.dataset.image_files import read_png
from satsight.dataset.journal import write_bytes_atomic
from satsight.dataset.preview import (
    PreviewStretch,
    crop_box_xyxy_px,
    thumbnail,
    write_contact_sheet,
)

#: Frames shown on the contact sheet at most, spread evenly over the dataset: a sheet of
#: every frame grows without bound (72 frames made an unreadable 1260 x 11520 px image).
CONTACT_SHEET_MAX_FRAMES = 36
THUMBNAIL_FOLDER = ".thumbnails"
THUMBNAIL_SIDE_PX = 256
_SOURCES = ("dn_png16", "preview_png8")


def contact_sheet_frames(count: int) -> list[int]:
    """Frame indices on the contact sheet: all, or an even spread of at most the maximum."""
    if count <= CONTACT_SHEET_MAX_FRAMES:
        return list(range(count))
    spread = np.rint(np.linspace(0, count - 1, CONTACT_SHEET_MAX_FRAMES)).astype(int)
    return sorted(set(spread.tolist()))


def thumbnail_source(record: dict) -> tuple[str, bool, list | None] | None:
    """(file key, from the crop?, box of the target) of the image a frame's thumbnail is
    made from, or None when the frame has no image file."""
    crop = record.get("crop") or {}
    for files, is_crop, bbox in (
        (record.get("files") or {}, False, record.get("bbox_xyxy_px")),
        (crop.get("files") or {}, True, crop.get("bbox_xyxy_px")),
    ):
        for key in _SOURCES:
            if key in files:
                return key, is_crop, bbox
    return None


def frame_thumbnail(image: np.ndarray, key: str, bbox: list | None, bias_dn: float) -> np.ndarray:
    """The (h, w) float thumbnail in [0, 1] of a uint16 DN or uint8 preview image, from
    the window around ``bbox`` (``crop_box_xyxy_px``; cut first: a 4096 x 4112 frame's
    conversion took 86 ms, its window's well under 1 ms)."""
    x0, y0, x1, y1 = crop_box_xyxy_px(bbox, image.shape)
    image = image[y0:y1, x0:x1].astype(np.float32)
    if key == "dn_png16":
        image = np.clip(image - np.float32(bias_dn), 0.0, None)
    return thumbnail(image[..., None], max_side_px=THUMBNAIL_SIDE_PX)[..., 0]


def _cache_path(root: Path, frame_index: int) -> Path:
    return Path(root) / THUMBNAIL_FOLDER / f"frame_{frame_index:06d}.npy"


def keep_thumbnail(
    root: Path,
    record: dict,
    dn: np.ndarray,
    bias_dn: float,
    full_well_dn: float,
    preview: PreviewStretch | None = None,
) -> None:
    """Keep the thumbnail of a frame being written (``dn``: the image it is made of, the
    full frame's or the crop's as ``thumbnail_source`` says), for the contact sheet.
    preview: the stretch of the frame's 8-bit preview (None: ``PreviewStretch()``), so that
    a thumbnail made from the preview equals the one a resumed run makes from its file."""
    source = thumbnail_source(record)
    if source is None:
        return
    key, _, bbox = source
    if key == "dn_png16":
        image = dn
    else:  # the stretch is per pixel: the window's pixels alone, then the whole window
        x0, y0, x1, y1 = crop_box_xyxy_px(bbox, dn.shape)
        image = (preview or PreviewStretch()).apply(dn[y0:y1, x0:x1], bias_dn, full_well_dn)
        bbox = None
    buffer = io.BytesIO()
    np.save(buffer, frame_thumbnail(image, key, bbox, bias_dn))
    path = _cache_path(root, record["frame_index"])
    path.parent.mkdir(exist_ok=True)
    write_bytes_atomic(path, buffer.getvalue())


def _load_thumbnail(root: Path, record: dict, bias_dn: float) -> np.ndarray | None:
    source = thumbnail_source(record)
    if source is None:
        return None
    try:
        return np.load(_cache_path(root, record["frame_index"]))
    except (OSError, ValueError):
        key, is_crop, bbox = source
        files = (record["crop"] if is_crop else record)["files"]
        return frame_thumbnail(read_png(root / files[key]), key, bbox, bias_dn)


def dataset_heading(manifest: dict) -> str:
    """The contact sheet's title: scenario, target, image size and focal length."""
    camera = manifest["camera"]
    width, height = camera["image_size_px"]
    return (
        f"{manifest['scenario']}: {manifest['target']['name']}, {width}x{height} px, "
        f"f = {camera['focal_length_m']:g} m"
    )


def write_dataset_contact_sheet(root: Path, manifest: dict, records: Sequence[dict]) -> bool:
    """Draw ``contact_sheet.png`` and drop the kept thumbnails; False when the frames have
    no image file to show."""
    root = Path(root)
    bias_dn = manifest["sensor"]["detector"]["bias_dn"]
    thumbs, titles = [], []
    for index in contact_sheet_frames(len(records)):
        record = records[index]
        image = _load_thumbnail(root, record, bias_dn)
        if image is None:
            break
        plan = record.get("plan", {})
        flags = "" if plan.get("visible", True) else "  [fails visibility]"
        thumbs.append(image)
        titles.append(
            f"#{record['frame_index']}  {record['range_m'] / 1e3:.3g} km, "
            f"phase {record['phase_angle_deg']:.0f}°{flags}\n"
            f"{record['object_pixel_count']} px on target"
        )
    if thumbs:
        shown = f" ({len(thumbs)} of {len(records)} frames)" if len(thumbs) < len(records) else ""
        write_contact_sheet(
            root / "contact_sheet.png", thumbs, titles, dataset_heading(manifest) + shown
        )
    shutil.rmtree(root / THUMBNAIL_FOLDER, ignore_errors=True)
    return bool(thumbs)
