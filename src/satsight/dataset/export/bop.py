"""Export to the BOP format (scene-wise layout), one scene per split.

Source of the format: bop_toolkit docs/bop_datasets_format.md ("BOP-scenewise") and
bop_toolkit_lib/inout.py (``save_json``, ``load_cam_params``), misc.py (``calc_2d_bbox``),
scripts/calc_gt_info.py and scripts/calc_model_info.py. Layout written::

    OUT/camera.json                          cx, cy, fx, fy, height, width
    OUT/models/obj_000001.ply, models_info.json
    OUT/test_targets_bop19.json              when the test split has visible targets
    OUT/{train,val,test}/000000/             one scene per non-empty split
        gray/IMID.png                        8-bit grey image
        depth/IMID.png                       16-bit depth, mm = value * depth_scale
        mask/IMID_000000.png, mask_visib/IMID_000000.png
        scene_camera.json, scene_gt.json, scene_gt_info.json

IMID is the satsight frame_index (six digits). Poses: ``cam_R_m2c`` (row-major) and
``cam_t_m2c`` (mm) with ``x_cam = R @ x_model + t``: satsight's R(q_cam_from_body) and
t_cam_from_body_m * 1000, the model frame being the body frame. satsight has a single
target that only it can hide, so its mask is both ``mask`` and ``mask_visib``.

The images are written on a few threads with a bounded number in flight, and the scene
JSON files entry by entry as they are (``JsonEntries``): memory does not grow with the
number of images.
"""

from __future__ import annotations

import json
import shutil
from array import array
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, ThreadPoolExecutor
from pathlib import Path

import numpy as np

from satsight.dataset.export.bop_model import MM_PER_M, write_bop_model
from satsight.dataset.export.json_entries import JsonEntries
from satsight.dataset.export.source import (
    ExportFrame,
    ExportFrames,
    read_depth_m,
    read_gray8,
    read_mask,
    require_file,
    require_image,
)
from satsight.dataset.image_files import encode_png
from satsight.dataset.labels import mask_bbox_xyxy_px
from satsight.dataset.reader import Dataset
from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion

OBJ_ID = 1
SCENE_ID = 0
GT_ID = 0  # the one annotated instance per image
UINT16_MAX = 65535
#: Smallest depth_scale written (mm per depth unit).
MIN_DEPTH_SCALE = 0.01
_PURPOSE = "the BOP export"
_WORKERS = 2
_IN_FLIGHT = 4 * _WORKERS


def bop_json_text(content: dict | list) -> str:
    """JSON laid out as bop_toolkit's ``save_json`` writes it.

    A dict: one top-level key per line, keys sorted (integer image ids numerically),
    each value on its line with sorted keys; a list: one element per line.
    """

    def dumps(value: object) -> str:
        return json.dumps(value, sort_keys=True, allow_nan=False)

    if isinstance(content, dict):
        lines = [f'  "{key}": {dumps(value)}' for key, value in sorted(content.items())]
        return "{\n" + ",\n".join(lines) + ("\n}" if lines else "}")
    lines = [f"  {dumps(value)}" for value in content]
    return "[\n" + ",\n".join(lines) + ("\n]" if lines else "]")


def write_bop_json(path: Path, content: dict | list) -> None:
    path.write_text(bop_json_text(content), encoding="utf-8")


def bop_json_entries(path: Path, kind: type = dict) -> JsonEntries:
    """A BOP JSON file written entry by entry, with the bytes of ``write_bop_json``; a
    dict's image ids must come in increasing order."""
    return JsonEntries(path, kind, sort_keys=True, final_newline=False)


def ordered_map(pool: Executor, function: Callable, items: Iterable, in_flight: int) -> Iterator:
    """``function(item)`` of each item on ``pool``, the results in the items' order, with
    at most ``in_flight`` items submitted and not yet taken."""
    pending: deque = deque()
    try:
        for item in items:
            pending.append(pool.submit(function, item))
            if len(pending) >= in_flight:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        for future in pending:
            future.cancel()


def depth_scale_for(max_depth_mm: float) -> float:
    """The smallest 1-2-5 value s (>= MIN_DEPTH_SCALE) with max_depth_mm / s < 65535.

    The depth PNG then holds round(depth_mm / s); its quantum is s mm. 1.0 when there is
    no surface in the image.
    """
    if not np.isfinite(max_depth_mm) or max_depth_mm < 0:
        raise SatsightError(f"depth must be finite and >= 0, got {max_depth_mm} mm")
    if max_depth_mm == 0:
        return 1.0
    for exponent in range(-2, 30):
        for mantissa in (1, 2, 5):
            scale = float(f"{mantissa}e{exponent}")
            if scale >= MIN_DEPTH_SCALE and max_depth_mm / scale < UINT16_MAX:
                return scale
    raise SatsightError(f"depth of {max_depth_mm} mm is too large to store")


def depth_png(depth_m: np.ndarray) -> tuple[np.ndarray, float]:
    """(uint16 image, depth_scale): depth in mm = value * depth_scale; 0 = no surface."""
    depth_mm = depth_m * MM_PER_M
    scale = depth_scale_for(float(depth_mm.max(initial=0.0)))
    values = np.rint(depth_mm / scale)
    # A surface never reads as "no surface", however close it is.
    values = np.where(depth_mm > 0, np.maximum(values, 1), 0)
    return values.astype(np.uint16), scale


def bop_bbox(bbox_xyxy_px: list[int] | None) -> list[int]:
    """[x, y, w, h] as bop_toolkit's calc_2d_bbox gives it: w = x_max - x_min (inclusive
    pixel indices, so a one-pixel silhouette has w = 0); [-1, -1, -1, -1] when empty."""
    if bbox_xyxy_px is None:
        return [-1, -1, -1, -1]
    x0, y0, x1, y1 = (int(v) for v in bbox_xyxy_px)
    return [x0, y0, x1 - x0, y1 - y0]


def _frame_entries(
    frame: ExportFrame, scene_dir: Path, header: dict, with_depth: bool
) -> tuple[dict, dict, dict, str]:
    """Write one image's files; its scene_camera, scene_gt and scene_gt_info entries."""
    im = f"{frame.frame_index:06d}"
    if "preview_png8" in frame.files:  # already the 8-bit image: copied as it is
        shutil.copyfile(require_image(frame, _PURPOSE), scene_dir / "gray" / f"{im}.png")
        image_key = "preview_png8"
    else:
        gray, image_key = read_gray8(frame, header, _PURPOSE)
        (scene_dir / "gray" / f"{im}.png").write_bytes(encode_png(gray))
    mask = read_mask(frame, _PURPOSE)
    mask_bytes = encode_png(mask.astype(np.uint8) * np.uint8(255))
    for folder in ("mask", "mask_visib"):
        (scene_dir / folder / f"{im}_{GT_ID:06d}.png").write_bytes(mask_bytes)
    camera = {"cam_K": frame.K.reshape(-1).tolist()}
    valid = 0
    if with_depth:
        depth, scale = depth_png(read_depth_m(frame, _PURPOSE))
        (scene_dir / "depth" / f"{im}.png").write_bytes(encode_png(depth))
        camera["depth_scale"] = scale
        valid = int(np.count_nonzero(depth[mask]))
    rotation = matrix_from_quaternion(frame.q_cam_from_body)
    gt = {
        "cam_R_m2c": rotation.reshape(-1).tolist(),
        "cam_t_m2c": (frame.t_cam_from_body_m * MM_PER_M).tolist(),
        "obj_id": OBJ_ID,
    }
    count = int(np.count_nonzero(mask))
    box = bop_bbox(mask_bbox_xyxy_px(mask))
    info = {
        "bbox_obj": box,
        "bbox_visib": box,
        "px_count_all": count,
        "px_count_valid": valid,
        "px_count_visib": count,
        "visib_fract": 1.0 if count > 0 else 0.0,
    }
    return camera, gt, info, image_key


def write_bop_split(
    frames: Iterable[ExportFrame],
    split_dir: Path,
    header: dict,
    with_depth: bool,
    visible_ids: array | None = None,
) -> set[str]:
    """Write one split's scene 000000; returns the image sources. The image ids whose
    target shows (px_count_visib > 0) are appended to ``visible_ids`` when given."""
    scene_dir = split_dir / f"{SCENE_ID:06d}"
    folders = ["gray", "mask", "mask_visib"] + (["depth"] if with_depth else [])
    for folder in folders:
        (scene_dir / folder).mkdir(parents=True, exist_ok=True)
    sources: set[str] = set()

    def entries(frame: ExportFrame) -> tuple[int, tuple[dict, dict, dict, str]]:
        return frame.frame_index, _frame_entries(frame, scene_dir, header, with_depth)

    with (
        ThreadPoolExecutor(max_workers=_WORKERS) as pool,
        bop_json_entries(scene_dir / "scene_camera.json") as cameras,
        bop_json_entries(scene_dir / "scene_gt.json") as gts,
        bop_json_entries(scene_dir / "scene_gt_info.json") as infos,
    ):
        for im_id, (camera, gt, info, source) in ordered_map(pool, entries, frames, _IN_FLIGHT):
            cameras.add(im_id, camera)
            gts.add(im_id, [gt])
            infos.add(im_id, [info])
            sources.add(source)
            if visible_ids is not None and info["px_count_visib"] > 0:
                visible_ids.append(im_id)
    return sources


def camera_json(dataset: Dataset, first: ExportFrame) -> dict:
    """BOP camera.json (for sensor simulation): the full camera, or one crop-sized camera
    with the principal point at the crop centre (each image's exact K is its cam_K);
    ``first``: the first frame exported."""
    if first.crop:
        width, height = first.size_px
        K = first.K.copy()
        K[0, 2], K[1, 2] = (width - 1) / 2.0, (height - 1) / 2.0
    else:
        camera = dataset.header.get("camera") or {}
        K = np.asarray(camera.get("K", first.K), dtype=np.float64)
        width, height = camera.get("image_size_px", first.size_px)
    return {
        "cx": float(K[0, 2]),
        "cy": float(K[1, 2]),
        "fx": float(K[0, 0]),
        "fy": float(K[1, 1]),
        "height": int(height),
        "width": int(width),
    }


def write_bop(dataset: Dataset, splits: dict[str, ExportFrames], root: Path) -> list[str]:
    """Write the BOP export of ``splits`` (name -> frames) into ``root``; returns notes.

    Three passes over the frames: which have depth, what each needs (checked before
    anything large is written), then the images and JSON files, split by split.
    """
    with_depth = all("depth_exr" in f.files for split in splits.values() for f in split)
    first = None
    for split in splits.values():
        for frame in split:  # fail before writing anything large
            first = frame if first is None else first
            require_image(frame, _PURPOSE)
            require_file(frame, "object_mask_png", "BOP's masks and scene_gt_info.json")
            if with_depth:
                require_file(frame, "depth_exr", _PURPOSE)
    model = dataset.header.get("target", {}).get("model_obj", "model/target.obj")
    info_entry = write_bop_model(dataset.root / model, root / "models", OBJ_ID)
    write_bop_json(root / "models" / "models_info.json", {OBJ_ID: info_entry})
    write_bop_json(root / "camera.json", camera_json(dataset, first))
    sources: set[str] = set()
    targets = array("q")  # test images showing the target
    for name, split_frames in splits.items():
        if not len(split_frames):
            continue
        visible = targets if name == "test" else None
        sources |= write_bop_split(split_frames, root / name, dataset.header, with_depth, visible)
    if targets:
        with bop_json_entries(root / "test_targets_bop19.json", list) as entries:
            for im_id in targets:
                entries.append(
                    {"im_id": im_id, "inst_count": 1, "obj_id": OBJ_ID, "scene_id": SCENE_ID}
                )
    gray = {
        frozenset({"preview_png8"}): "gray: 8-bit previews",
        frozenset({"dn_png16"}): "gray: DN stretched to 8 bits (no previews)",
    }.get(frozenset(sources), "gray: 8-bit previews, DN stretched where none")
    depth = "depth: 16-bit PNG, per-image depth_scale" if with_depth else "no depth"
    notes = [gray, depth]
    return notes
