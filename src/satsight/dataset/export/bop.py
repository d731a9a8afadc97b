"""Export to the BOP format (scene-wise layout), one scene per split.

Source of the format: bop_toolkit docs/bop_datasets_format.md ("BOP-scenewise") and
bop_toolkit_lib/inout.py (``save_json``, ``load_cam_params``), misc.py (``calc_2d_bbox``),
scripts/calc_gt_info.py and scripts/calc_model_info.py. Layout written::

    OUT/camera.json                          cx, cy, fx, fy, height, width
    OUT/models/obj_000001.ply, models_info.json
    OUT/models_eval/                         the same (BOP's evaluation models)
    OUT/test_targets_bop19.json, _bop24.json when the test split has visible targets
    OUT/BOP_TOOLKIT.md                       how to register the export in bop_toolkit
    OUT/{train,val,test}/000000/             one scene per non-empty split
        gray/IMID.png                        grey image (``images.py``: 16-bit DN by default)
        depth/IMID.png                       16-bit depth, mm = value * depth_scale
        mask/IMID_000000.png, mask_visib/IMID_000000.png
        scene_camera.json, scene_gt.json, scene_gt_info.json

IMID is the satsight frame_index (six digits). Poses: ``cam_R_m2c`` (row-major) and
``cam_t_m2c`` (mm) with ``x_cam = R @ x_model + t``: satsight's R(q_cam_from_body) and
t_cam_from_body_m * 1000, the model frame being the body frame. The target is the one
BOP object. Without other objects in the scene only it can hide itself, so its mask is
both ``mask`` and ``mask_visib``; with ``objects`` (debris, another spacecraft) ``mask`` is
its amodal mask (the whole silhouette, also behind them) and ``mask_visib`` its visible
pixels, and ``visib_fract`` their ratio. The silhouette cut off by the image border counts
in ``px_count_all`` and ``bbox_obj`` (``silhouette.py``), as in bop_toolkit's
calc_gt_info.py.

Pixels: bop_toolkit's renderers (renderer_vispy.py ``_calc_calib_proj``: the OpenGL
projection maps x_cam to window x = fx X / Z + cx, and OpenGL puts pixel i's centre at
window x = i + 0.5) place pixel corners at integers; satsight places pixel centres there.
``cam_K`` therefore has cx, cy + 0.5, so the toolkit renders the model onto the pixels
satsight's mask holds.

The images are written on a few threads with a bounded number in flight, and the scene
JSON files entry by entry as they are (``JsonEntries``): memory does not grow with the
number of images.
"""

from __future__ import annotations

import json
import math
import shutil
from array import array
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.dataset.export.bop_model import MM_PER_M, write_bop_model
from satsight.dataset.export.bop_toolkit_notes import TOOLKIT_NOTES, toolkit_notes
from satsight.dataset.export.images import ExportImages
from satsight.dataset.export.json_entries import JsonEntries
from satsight.dataset.export.silhouette import outside_silhouette
from satsight.dataset.export.source import (
    ExportFrame,
    ExportFrames,
    read_amodal_mask,
    read_depth_m,
    read_mask,
    require_file,
)
from satsight.dataset.image_files import encode_png
from satsight.dataset.labels import mask_bbox_xyxy_px
from satsight.dataset.reader import Dataset
from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.scene.loading import load_mesh

OBJ_ID = 1
SCENE_ID = 0
GT_ID = 0  # the one annotated instance per image
#: satsight pixel position + this = bop_toolkit's pixel position (module docstring).
PIXEL_OFFSET_PX = 0.5
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


def bop_K(K: np.ndarray) -> np.ndarray:
    """satsight intrinsics (pixel centres at integers) -> BOP ``cam_K`` (pixel corners at
    integers, the convention of bop_toolkit's renderers): cx, cy + 0.5 px."""
    out = np.array(K, dtype=np.float64)
    out[0, 2] += PIXEL_OFFSET_PX
    out[1, 2] += PIXEL_OFFSET_PX
    return out


@dataclass(frozen=True)
class BopFrameRule:
    """What every image of a BOP export shares: how images are made, whether depth is
    written, and the model (body frame, metres) whose silhouette beyond the image border
    ``px_count_all`` and ``bbox_obj`` count."""

    images: ExportImages
    with_depth: bool
    vertices_m: np.ndarray
    faces: np.ndarray


def gt_info(
    frame: ExportFrame,
    mask: np.ndarray,
    valid: int,
    rule: BopFrameRule,
    amodal: np.ndarray | None = None,
) -> dict:
    """One scene_gt_info entry, as bop_toolkit's calc_gt_info.py defines it.

    mask: the target's visible pixels. amodal: its whole silhouette in the image, also
    where other objects hide it (None: nothing but itself can, so it is ``mask``). The
    whole silhouette adds the pixels cut off by the image border (``outside_silhouette``).
    """
    count = int(np.count_nonzero(mask))
    box = mask_bbox_xyxy_px(mask)
    inside = count if amodal is None else int(np.count_nonzero(amodal))
    inside_box = box if amodal is None else mask_bbox_xyxy_px(amodal)
    outside = outside_silhouette(
        rule.vertices_m,
        rule.faces,
        matrix_from_quaternion(frame.q_cam_from_body),
        frame.t_cam_from_body_m,
        frame.K,
        frame.size_px,
    )
    total = inside + outside.pixel_count
    whole = inside_box
    if outside.bbox_xyxy_px is not None and inside_box is not None:
        boxes = np.array([inside_box, outside.bbox_xyxy_px])
        whole = [*boxes[:, :2].min(axis=0).tolist(), *boxes[:, 2:].max(axis=0).tolist()]
    visible = count > 0
    return {
        # calc_gt_info.py gives the object's box only when some of it is visible
        "bbox_obj": bop_bbox(whole if visible else None),
        "bbox_visib": bop_bbox(box),
        "px_count_all": total,
        "px_count_valid": valid,
        "px_count_visib": count,
        "visib_fract": count / total if total > 0 else 0.0,
    }


def _frame_entries(
    frame: ExportFrame, scene_dir: Path, rule: BopFrameRule
) -> tuple[dict, dict, dict]:
    """Write one image's files; its scene_camera, scene_gt and scene_gt_info entries."""
    im = f"{frame.frame_index:06d}"
    rule.images.write(frame, frame.camera_mode, scene_dir / "gray" / f"{im}.png", _PURPOSE)
    mask = read_mask(frame, _PURPOSE)
    amodal = read_amodal_mask(frame)
    visib_bytes = encode_png(mask.astype(np.uint8) * np.uint8(255))
    mask_bytes = visib_bytes if amodal is None else encode_png(amodal.astype(np.uint8) * 255)
    (scene_dir / "mask" / f"{im}_{GT_ID:06d}.png").write_bytes(mask_bytes)
    (scene_dir / "mask_visib" / f"{im}_{GT_ID:06d}.png").write_bytes(visib_bytes)
    camera = {"cam_K": bop_K(frame.K).reshape(-1).tolist()}
    valid = 0
    if rule.with_depth:
        depth, scale = depth_png(read_depth_m(frame, _PURPOSE))
        (scene_dir / "depth" / f"{im}.png").write_bytes(encode_png(depth))
        camera["depth_scale"] = scale
        # calc_gt_info.py: the silhouette's pixels with a depth measurement
        valid = int(np.count_nonzero(depth[mask if amodal is None else amodal]))
    rotation = matrix_from_quaternion(frame.q_cam_from_body)
    gt = {
        "cam_R_m2c": rotation.reshape(-1).tolist(),
        "cam_t_m2c": (frame.t_cam_from_body_m * MM_PER_M).tolist(),
        "obj_id": OBJ_ID,
    }
    return camera, gt, gt_info(frame, mask, valid, rule, amodal)


def write_bop_split(
    frames: Iterable[ExportFrame],
    split_dir: Path,
    rule: BopFrameRule,
    visible_ids: array | None = None,
) -> SplitSummary:
    """Write one split's scene 000000. The image ids whose target shows (px_count_visib
    > 0) are appended to ``visible_ids`` when given."""
    scene_dir = split_dir / f"{SCENE_ID:06d}"
    folders = ["gray", "mask", "mask_visib"] + (["depth"] if rule.with_depth else [])
    for folder in folders:
        (scene_dir / folder).mkdir(parents=True, exist_ok=True)
    summary = SplitSummary()

    def entries(frame: ExportFrame) -> tuple[int, tuple[dict, dict, dict]]:
        return frame.frame_index, _frame_entries(frame, scene_dir, rule)

    with (
        ThreadPoolExecutor(max_workers=_WORKERS) as pool,
        bop_json_entries(scene_dir / "scene_camera.json") as cameras,
        bop_json_entries(scene_dir / "scene_gt.json") as gts,
        bop_json_entries(scene_dir / "scene_gt_info.json") as infos,
    ):
        for im_id, (camera, gt, info) in ordered_map(pool, entries, frames, _IN_FLIGHT):
            cameras.add(im_id, camera)
            gts.add(im_id, [gt])
            infos.add(im_id, [info])
            summary.add(camera, gt, info)
            if visible_ids is not None and info["px_count_visib"] > 0:
                visible_ids.append(im_id)
    return summary


@dataclass
class SplitSummary:
    """What the toolkit's registration needs to know of the images written: how many,
    the largest depth_scale (mm per depth unit) and the camera-object distances (mm)."""

    images: int = 0
    max_depth_scale_mm: float = 0.0
    min_distance_mm: float = math.inf
    max_distance_mm: float = 0.0

    def add(self, camera: dict, gt: dict, info: dict) -> None:
        self.images += 1
        self.max_depth_scale_mm = max(self.max_depth_scale_mm, camera.get("depth_scale", 0.0))
        distance = float(np.linalg.norm(gt["cam_t_m2c"]))
        self.min_distance_mm = min(self.min_distance_mm, distance)
        self.max_distance_mm = max(self.max_distance_mm, distance)

    def merge(self, other: SplitSummary) -> None:
        self.images += other.images
        self.max_depth_scale_mm = max(self.max_depth_scale_mm, other.max_depth_scale_mm)
        self.min_distance_mm = min(self.min_distance_mm, other.min_distance_mm)
        self.max_distance_mm = max(self.max_distance_mm, other.max_distance_mm)


def camera_json(dataset: Dataset, first: ExportFrame) -> dict:
    """BOP camera.json (for sensor simulation): the full camera, or one crop-sized camera
    with the principal point at the crop centre (each image's exact K is its cam_K);
    ``first``: the first frame exported. In BOP's pixel convention (``bop_K``)."""
    if first.crop:
        width, height = first.size_px
        K = first.K.copy()
        K[0, 2], K[1, 2] = (width - 1) / 2.0, (height - 1) / 2.0
    else:
        camera = dataset.header.get("camera") or {}
        K = np.asarray(camera.get("K", first.K), dtype=np.float64)
        width, height = camera.get("image_size_px", first.size_px)
    K = bop_K(K)
    return {
        "cx": float(K[0, 2]),
        "cy": float(K[1, 2]),
        "fx": float(K[0, 0]),
        "fy": float(K[1, 1]),
        "height": int(height),
        "width": int(width),
    }


def write_targets(root: Path, im_ids: array) -> None:
    """The test targets of BOP's evaluation scripts: ``test_targets_bop19.json`` (pose
    estimation: one instance of object 1 per image) and ``test_targets_bop24.json``
    (detection: the images), for the test images showing the target."""
    with bop_json_entries(root / "test_targets_bop19.json", list) as entries:
        for im_id in im_ids:
            entries.append(
                {"im_id": im_id, "inst_count": 1, "obj_id": OBJ_ID, "scene_id": SCENE_ID}
            )
    with bop_json_entries(root / "test_targets_bop24.json", list) as entries:
        for im_id in im_ids:
            entries.append({"im_id": im_id, "scene_id": SCENE_ID})


def write_bop(
    dataset: Dataset,
    splits: dict[str, ExportFrames],
    root: Path,
    images: ExportImages,
    export_name: str,
) -> list[str]:
    """Write the BOP export of ``splits`` (name -> frames) into ``root``; returns notes.
    export_name: the export folder's final name (``root`` may be where it is staged).

    Three passes over the frames: which have depth, what each needs (checked before
    anything large is written), then the images and JSON files, split by split.
    """
    with_depth = all("depth_exr" in f.files for split in splits.values() for f in split)
    first = None
    for split in splits.values():
        for frame in split:  # fail before writing anything large
            first = frame if first is None else first
            images.require(frame, _PURPOSE)
            require_file(frame, "object_mask_png", "BOP's masks and scene_gt_info.json")
            if with_depth:
                require_file(frame, "depth_exr", _PURPOSE)
    model = dataset.root / dataset.header.get("target", {}).get("model_obj", "model/target.obj")
    mesh = load_mesh(model)
    info_entry = write_bop_model(mesh, root / "models", OBJ_ID)
    write_bop_json(root / "models" / "models_info.json", {OBJ_ID: info_entry})
    # BOP's error functions read models_eval/: the same model (its vertices hold the
    # maxima MSSD and MSPD look for, as the convex hull's corners are among them).
    shutil.copytree(root / "models", root / "models_eval")
    camera = camera_json(dataset, first)
    write_bop_json(root / "camera.json", camera)
    rule = BopFrameRule(images, with_depth, mesh.vertices_m, mesh.faces)
    totals = SplitSummary()
    targets = array("q")  # test images showing the target
    written = []
    for name, split_frames in splits.items():
        if not len(split_frames):
            continue
        visible = targets if name == "test" else None
        totals.merge(write_bop_split(split_frames, root / name, rule, visible))
        written.append(name)
    if targets:
        write_targets(root, targets)
    (root / TOOLKIT_NOTES).write_text(
        toolkit_notes(export_name, camera, info_entry, totals, written, with_depth, bool(targets)),
        encoding="utf-8",
    )
    depth = "depth: 16-bit PNG, per-image depth_scale" if with_depth else "no depth"
    return [images.note(), depth, "cam_K: principal point +0.5 px (BOP pixel origin)"]
