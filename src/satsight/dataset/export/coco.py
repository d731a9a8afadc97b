"""Export to the COCO object-detection format: boxes, RLE masks and keypoints.

Source of the format: the COCO "Data format" page (cocodataset.org/#format-data: object
detection annotations, keypoint detection) and pycocotools (``coco.py``: ``COCO``,
``annToRLE``; ``cocoeval.py``: ``COCOeval``; ``common/maskApi.c``: ``rleToBbox``,
``rleArea``, ``rleToString``). Layout written::

    OUT/images/{train,val,test}/NNNNNN.png    the image (``images.py``: 16-bit DN above
                                              the bias by default), NNNNNN = frame_index
    OUT/annotations/instances_{split}.json    {info, licenses, categories, images, annotations}

one of each per non-empty split (an empty split has neither, as in the BOP export).
``file_name`` is relative to ``OUT/images/{split}/``, the image folder a COCO loader is
given (as COCO's own ``train2017/``). Image and annotation ``id`` are frame_index + 1:
COCO ids are positive, and COCOeval takes a matched annotation id of 0 for "unmatched".

Pixel conventions:

- Boxes and segmentations use continuous coordinates with pixel corners at integers:
  pixel (i, j) covers [i, i + 1) x [j, j + 1). pycocotools' ``rleToBbox`` gives a mask
  whose inclusive pixel indices run x0..x1, y0..y1 the box [x0, y0, x1 - x0 + 1,
  y1 - y0 + 1]; ``bbox`` is exactly that of the object mask (satsight's ``bbox_xyxy_px``
  [x0, y0, x1, y1]), and ``area`` the mask's pixel count (``rleArea``).
- Keypoints are pixel indices, pixel centres at integers (detectron2
  ``data/datasets/coco.py``, ``load_coco_json``: COCO keypoints are "integers in [0, H-1
  or W-1]", read as pixel indices, and +0.5 is added to reach its corner convention):
  satsight's own convention, so ``keypoints`` holds satsight's ``keypoints_px``
  unchanged, and the extra ``K`` of each image (satsight's, pixel (0, 0) the centre of the
  top-left pixel) projects the body keypoints onto them.
- Visibility v: 2 where the keypoint is visible, 1 where it projects inside the image
  (within the outer edges of the border pixels) but is hidden, 0 with x = y = 0 where it
  lies outside the image or at or behind the camera; ``num_keypoints`` counts v > 0. The
  flags come from the view's ``keypoints_visible``; for a record without them, from the
  view's depth image by the rule that makes them (``labels.keypoints_visible``), and
  without depth every keypoint inside the image gets v = 2 (its visibility is unknown;
  the export's notes say so).

Segmentation: COCO's compressed RLE (``rle.py``), the form pycocotools writes for results
and reads for ground truth (as MMDetection does, and detectron2 with ``INPUT.MASK_FORMAT
bitmask``): a few characters per image column the target covers, several times shorter
than the list of run lengths. Masks are the visible pixels (the object mask: the target
where nothing hides it); ``iscrowd`` is 0. An image where the target covers no pixel has
no annotation of it.

Other objects (the scenario's ``objects``): each is a category of its own, id = its object
id (2, 3, ... in the scenario's order, as in ``masks/*_object_ids.png``), name its name,
supercategory ``object``, no keypoints; an image has one annotation per object it sees,
its visible pixels from the object-id image, with ``keypoints`` empty and
``num_keypoints`` 0 (so COCOeval's keypoint evaluation ignores it). With objects, an
annotation's id is image_id x 256 + object id (the target's object id is 1), so ids stay
unique with several annotations per image; without them it is the image id, as before.

The images are written on a few threads with a bounded number in flight; each split's
``images`` and ``annotations`` lists are written entry by entry into two part files
(``JsonEntries``) and joined into the annotation file at the end: memory does not grow
with the number of images.
"""

from __future__ import annotations

import json
import shutil
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.dataset.export.bop import ordered_map
from satsight.dataset.export.images import ExportImages
from satsight.dataset.export.json_entries import JsonEntries
from satsight.dataset.export.rle import encode_rle
from satsight.dataset.export.source import (
    ExportFrame,
    ExportFrames,
    read_depth_m,
    read_mask,
    read_object_ids,
    require_file,
)
from satsight.dataset.labels import keypoints_visible, mask_bbox_xyxy_px
from satsight.dataset.reader import Dataset
from satsight.errors import SatsightError
from satsight.frames.quaternion import canonical_quaternion, matrix_from_quaternion

CATEGORY_ID = 1
SUPERCATEGORY = "spacecraft"
#: Supercategory of the scene's other objects (debris, other spacecraft, placed meshes).
OBJECT_SUPERCATEGORY = "object"
#: With other objects, annotation id = image id x OBJECT_ID_SPAN + object id (ids < 256).
OBJECT_ID_SPAN = 256
#: The category name when the manifest names no target.
DEFAULT_CATEGORY_NAME = "target"
#: COCO visibility flags: not labelled (outside the image), labelled but hidden, visible.
V_OUTSIDE, V_HIDDEN, V_VISIBLE = 0, 1, 2
#: Where each view's visibility flags came from (module docstring).
FROM_LABELS, FROM_DEPTH, UNKNOWN = "labels", "depth", "unknown"
_PURPOSE = "the COCO export"
_WORKERS = 2
_IN_FLIGHT = 4 * _WORKERS


def image_id(frame_index: int) -> int:
    """The COCO image id (and annotation id) of a frame: frame_index + 1."""
    return int(frame_index) + 1


def annotation_id(frame_index: int, object_id: int, with_objects: bool) -> int:
    """The id of an annotation: the image id where the dataset has no other objects (one
    annotation per image), else image id x 256 + object id (1 the target, 2.. objects)."""
    if not with_objects:
        return image_id(frame_index)
    return image_id(frame_index) * OBJECT_ID_SPAN + int(object_id)


def image_name(frame_index: int) -> str:
    """The image's file name in ``images/{split}/``: six-digit frame_index."""
    return f"{int(frame_index):06d}.png"


def coco_bbox(bbox_xyxy_px: list[int]) -> list[int]:
    """satsight's [x0, y0, x1, y1] (inclusive pixel indices) -> COCO's [x, y, w, h] with
    pixel corners at integers: [x0, y0, x1 - x0 + 1, y1 - y0 + 1] (``rleToBbox``)."""
    x0, y0, x1, y1 = (int(v) for v in bbox_xyxy_px)
    return [x0, y0, x1 - x0 + 1, y1 - y0 + 1]


def inside_image(points_px: np.ndarray, size_px: tuple[int, int]) -> np.ndarray:
    """(N,) bool: which pixel positions (N, 2) fall in an image of size (W, H), within the
    outer edges of its border pixels (NaN: behind the camera, outside)."""
    width, height = size_px
    u, v = np.asarray(points_px, dtype=np.float64).T
    with np.errstate(invalid="ignore"):
        return (u >= -0.5) & (u < width - 0.5) & (v >= -0.5) & (v < height - 0.5)


def keypoint_flags(
    points_px: np.ndarray, size_px: tuple[int, int], visible: np.ndarray | None
) -> np.ndarray:
    """(N,) COCO v of each keypoint: 2 visible, 1 inside the image but hidden, 0 outside
    or behind the camera. visible: the (N,) flags, or None when unknown (then every
    keypoint inside the image is 2)."""
    inside = inside_image(points_px, size_px)
    seen = np.ones(len(inside), dtype=bool) if visible is None else np.asarray(visible, bool)
    return np.where(inside, np.where(seen, V_VISIBLE, V_HIDDEN), V_OUTSIDE)


def coco_keypoints(points_px: np.ndarray, flags: np.ndarray) -> list:
    """[x1, y1, v1, x2, y2, v2, ...]: satsight's pixel positions unchanged, x = y = 0
    where v = 0."""
    out: list = []
    for (u, v), flag in zip(np.asarray(points_px, dtype=np.float64), flags, strict=True):
        out += [float(u), float(v), int(flag)] if flag else [0, 0, 0]
    return out


@dataclass(frozen=True)
class CocoFrameRule:
    """What every image of a COCO export shares: how images are made, the target's
    keypoints in its body frame ((N, 3) metres, or None when the manifest has none), and
    the scene's other objects (object id -> name; empty without them)."""

    images: ExportImages
    keypoint_count: int
    keypoints_body_m: np.ndarray | None
    objects: dict[int, str]


def _keypoints_body_m(header: dict) -> np.ndarray | None:
    """The manifest's (N, 3) body keypoints (metres), or None."""
    try:
        points = np.array((header.get("target") or {})["keypoints_body_m"], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        return None
    return points if points.ndim == 2 and points.shape[1] == 3 and len(points) else None


def _visibility(frame: ExportFrame, rule: CocoFrameRule) -> tuple[np.ndarray | None, str]:
    """The frame's keypoint visibility flags and where they came from."""
    if frame.keypoints_visible is not None:
        return frame.keypoints_visible, FROM_LABELS
    depth_z = frame.keypoints_depth_m
    if depth_z is None and rule.keypoints_body_m is not None:
        rotation = matrix_from_quaternion(frame.q_cam_from_body)
        depth_z = (rule.keypoints_body_m @ rotation.T + frame.t_cam_from_body_m)[:, 2]
    if "depth_exr" not in frame.files or depth_z is None:
        return None, UNKNOWN
    depth = read_depth_m(frame, _PURPOSE)
    return keypoints_visible(frame.keypoints_px, depth_z, depth), FROM_DEPTH


def _check_frame(frame: ExportFrame, rule: CocoFrameRule) -> None:
    """Fail before writing anything large: the files and labels the frame needs."""
    rule.images.require(frame, _PURPOSE)
    require_file(frame, "object_mask_png", "COCO's segmentations and boxes")
    view = "crop" if frame.crop else "frame"
    points, flags = frame.keypoints_px, frame.keypoints_visible
    if points is None:
        raise SatsightError(
            f"{view} {frame.frame_index} has no keypoints_px; the dataset is damaged: regenerate it"
        )
    counts = {"keypoints_px": len(points)}
    if flags is not None:
        counts["keypoints_visible"] = len(flags)
    for what, count in counts.items():
        if count != rule.keypoint_count:
            raise SatsightError(
                f"{view} {frame.frame_index} has {count} {what} where the target has "
                f"{rule.keypoint_count} keypoints; the dataset is damaged: regenerate it"
            )
    if flags is None and "depth_exr" in frame.files:
        require_file(frame, "depth_exr", "the keypoints' visibility")
    if frame.objects:
        require_file(frame, "object_id_png", "the other objects' annotations")
    for object_id, name in frame.objects:
        if not 2 <= object_id < OBJECT_ID_SPAN:
            raise SatsightError(
                f"{view} {frame.frame_index} has an object id {object_id} outside 2-"
                f"{OBJECT_ID_SPAN - 1}; the dataset is damaged: regenerate it"
            )
        known = rule.objects.setdefault(object_id, name)
        if known != name:
            raise SatsightError(
                f"{view} {frame.frame_index} names object id {object_id} '{name}' where "
                f"other frames name it '{known}'; the dataset is damaged: regenerate it"
            )


def _mask_fields(mask: np.ndarray, box: list[int]) -> dict:
    """An annotation's box, area, crowd flag and RLE segmentation of a visible mask."""
    return {
        "bbox": coco_bbox(box),
        "area": int(np.count_nonzero(mask)),
        "iscrowd": 0,
        "segmentation": encode_rle(mask),
    }


def frame_entries(
    frame: ExportFrame, image_dir: Path, rule: CocoFrameRule
) -> tuple[dict, list[dict], str | None]:
    """Write one image; its COCO image entry, its annotations (the target's where it
    covers a pixel, then one per other object seen) and where the target's keypoint
    visibility came from (None without a target annotation)."""
    index = frame.frame_index
    rule.images.write(frame, frame.camera_mode, image_dir / image_name(index), _PURPOSE)
    width, height = frame.size_px
    image = {
        "id": image_id(index),
        "file_name": image_name(index),
        "width": int(width),
        "height": int(height),
        "frame_index": int(index),
        "q_cam_from_body": canonical_quaternion(frame.q_cam_from_body).tolist(),
        "t_cam_from_body_m": frame.t_cam_from_body_m.tolist(),
        "K": frame.K.tolist(),
    }
    with_objects = bool(rule.objects)
    annotations, source = [], None
    mask = read_mask(frame, _PURPOSE)
    box = mask_bbox_xyxy_px(mask)
    if box is not None:
        visible, source = _visibility(frame, rule)
        flags = keypoint_flags(frame.keypoints_px, frame.size_px, visible)
        annotations.append(
            {
                "id": annotation_id(index, 1, with_objects),
                "image_id": image_id(index),
                "category_id": CATEGORY_ID,
                **_mask_fields(mask, box),
                "keypoints": coco_keypoints(frame.keypoints_px, flags),
                "num_keypoints": int(np.count_nonzero(flags)),
            }
        )
    if frame.objects:
        ids = read_object_ids(frame, _PURPOSE)
        for object_id, _ in frame.objects:
            seen = ids == object_id
            object_box = mask_bbox_xyxy_px(seen)
            if object_box is None:
                continue
            annotations.append(
                {
                    "id": annotation_id(index, object_id, with_objects),
                    "image_id": image_id(index),
                    "category_id": int(object_id),
                    **_mask_fields(seen, object_box),
                    "keypoints": [],
                    "num_keypoints": 0,
                }
            )
    return image, annotations, source


def categories(
    header: dict, keypoint_count: int, objects: dict[int, str] | None = None
) -> list[dict]:
    """The dataset's target, with its keypoints ``kp_0`` ... and no skeleton, then one
    category per other object of the scene (id = object id, no keypoints)."""
    name = (header.get("target") or {}).get("name") or DEFAULT_CATEGORY_NAME
    out = [
        {
            "id": CATEGORY_ID,
            "name": str(name),
            "supercategory": SUPERCATEGORY,
            "keypoints": [f"kp_{k}" for k in range(keypoint_count)],
            "skeleton": [],
        }
    ]
    for object_id, object_name in sorted((objects or {}).items()):
        out.append(
            {
                "id": int(object_id),
                "name": str(object_name),
                "supercategory": OBJECT_SUPERCATEGORY,
                "keypoints": [],
                "skeleton": [],
            }
        )
    return out


def _join(path: Path, head: dict, parts: dict[str, Path]) -> None:
    """Write the JSON object ``head`` + {key: the JSON text in each part file} to
    ``path``, one top-level key per line, copying the parts in pieces; the parts are
    removed."""
    with open(path, "w", encoding="utf-8") as out:
        out.write("{\n")
        for key, value in head.items():
            out.write(f"  {json.dumps(key)}: {json.dumps(value, allow_nan=False)},\n")
        for number, (key, part) in enumerate(parts.items()):
            out.write(f"  {json.dumps(key)}: ")
            with open(part, encoding="utf-8") as stream:
                shutil.copyfileobj(stream, out)
            out.write(",\n" if number < len(parts) - 1 else "\n")
            part.unlink()
        out.write("}\n")


def write_coco_split(
    frames: ExportFrames, root: Path, name: str, head: dict, rule: CocoFrameRule
) -> Counter:
    """Write one split's images and ``annotations/instances_{name}.json``; returns how
    many annotated views took their keypoint visibility from each source."""
    image_dir = root / "images" / name
    image_dir.mkdir(parents=True)
    folder = root / "annotations"
    parts = {"images": folder / f".{name}.images.part", "annotations": folder / f".{name}.ann.part"}
    sources: Counter = Counter()
    with (
        ThreadPoolExecutor(max_workers=_WORKERS) as pool,
        JsonEntries(parts["images"], list) as images,
        JsonEntries(parts["annotations"], list) as annotations,
    ):
        work = ordered_map(pool, lambda f: frame_entries(f, image_dir, rule), frames, _IN_FLIGHT)
        for image, entries, source in work:
            images.append(image)
            for annotation in entries:
                annotations.append(annotation)
            if source is not None:
                sources[source] += 1
    _join(folder / f"instances_{name}.json", head, parts)
    return sources


def write_coco(
    dataset: Dataset, splits: dict[str, ExportFrames], root: Path, images: ExportImages
) -> list[str]:
    """Write the COCO export of ``splits`` (name -> frames) into ``root``; returns notes.

    Two passes over the frames: what each needs (checked before anything large is
    written), then the images and annotation files, split by split.
    """
    header = dataset.header
    body = _keypoints_body_m(header)
    rule = None
    for split in splits.values():
        for frame in split:
            if rule is None:  # without keypoints in the manifest, the first frame's count
                points = frame.keypoints_px
                count = len(body) if body is not None else len(points if points is not None else ())
                rule = CocoFrameRule(images, count, body, {})
            _check_frame(frame, rule)
    (root / "annotations").mkdir()
    sources: Counter = Counter()
    for name, split_frames in splits.items():
        if not len(split_frames):
            continue
        head = {
            "info": {
                "description": f"satsight dataset {header.get('scenario')}, {name} split",
                "contributor": "satsight",
                "url": "",
            },
            "licenses": [],
            "categories": categories(header, rule.keypoint_count, rule.objects),
        }
        sources += write_coco_split(split_frames, root, name, head, rule)
    notes = [images.note(), "segmentation: compressed RLE", "keypoints: pixel centres at integers"]
    if rule.objects:
        notes.append(
            f"{len(rule.objects)} other objects as categories {min(rule.objects)}-"
            f"{max(rule.objects)} (annotation id = image id x {OBJECT_ID_SPAN} + object id)"
        )
    if sources[FROM_DEPTH]:
        notes.append(
            f"keypoint visibility of {sources[FROM_DEPTH]} images from their depth (no "
            "keypoints_visible in the labels)"
        )
    if sources[UNKNOWN]:
        notes.append(
            f"keypoint visibility unknown in {sources[UNKNOWN]} images (no keypoints_visible, "
            "no depth): every keypoint inside the image is marked v=2"
        )
    return notes
