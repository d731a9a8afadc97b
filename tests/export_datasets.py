"""Small satsight datasets (format version 3) for the export tests.

``write_box_dataset`` builds one by hand, without the renderer: the target is a box off
the body origin, and its mask and depth come from an exact ray-box intersection through
each pixel centre, so every label is known in closed form. ``render_tiny_dataset``
renders a procedural satellite with ``satsight.run.generation.generate_dataset``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from satsight.dataset.image_files import write_exr, write_png
from satsight.dataset.labels import mask_bbox_xyxy_px
from satsight.dataset.preview import dn_preview_uint8
from satsight.frames.quaternion import canonical_quaternion, quaternion_from_matrix
from satsight.scene.mesh import TargetMesh
from satsight.scene.obj_export import write_obj

#: Box target: half sizes and centre in the body frame (metres), off the origin on purpose.
BOX_HALF_M = np.array([1.0, 0.6, 0.4])
BOX_CENTER_M = np.array([0.2, -0.1, 0.3])
FOCAL_M = 0.75
PITCH_M = 10e-6
SIZE_PX = (64, 48)
#: Camera-frame position of the box centre per frame (metres): the last one is 50 km away.
CENTERS_CAM_M = [(0.3, -0.2, 4000.0), (-0.4, 0.1, 5000.0), (0.0, 0.5, 4500.0), (0.1, 0.0, 50e3)]
#: Box centres that put the box across the image border (right, left and top, bottom).
TRUNCATED_CENTERS_CAM_M = [(1.5, 0.0, 4000.0), (-1.4, -0.7, 4500.0), (0.0, 1.0, 4200.0)]
DETECTOR = {"bias_dn": 1000.0, "full_well_e": 350000.0, "conversion_gain_e_per_dn": 5.833,
            "adc_bits": 16}  # fmt: skip
CROP_SIDE_PX = 32
ALL_KEYS = ("dn_png16", "preview_png8", "depth_exr", "object_mask_png", "part_mask_png16")
FOLDERS = {
    "dn_png16": ("images", ".png"),
    "preview_png8": ("previews", ".png"),
    "depth_exr": ("depth", ".exr"),
    "object_mask_png": ("masks", "_object.png"),
    "part_mask_png16": ("masks", "_parts.png"),
}


def box_K() -> np.ndarray:
    f = FOCAL_M / PITCH_M
    w, h = SIZE_PX
    return np.array([[f, 0.0, (w - 1) / 2.0], [0.0, f, (h - 1) / 2.0], [0.0, 0.0, 1.0]])


def box_mesh() -> TargetMesh:
    box = trimesh.creation.box(extents=2 * BOX_HALF_M)
    return TargetMesh(
        vertices_m=np.asarray(box.vertices) + BOX_CENTER_M,
        faces=np.asarray(box.faces),
        face_part_index=np.zeros(len(box.faces), dtype=np.int32),
        part_names=("bus",),
        part_materials=("mli_gold",),
        name="box",
    )


def box_pose(frame: int, centers_cam_m=CENTERS_CAM_M) -> tuple[np.ndarray, np.ndarray]:
    """(R_cam_from_body, t_cam_from_body_m) of a frame: a fixed random turn per frame."""
    R = Rotation.random(random_state=100 + frame).as_matrix()
    t = np.array(centers_cam_m[frame]) - R @ BOX_CENTER_M
    return R, t


def ray_cast_box(R: np.ndarray, t: np.ndarray, K: np.ndarray, size: tuple[int, int]):
    """Exact depth (m along +z_cam, 0 = miss) through each pixel centre; float64 (H, W)."""
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    d_cam = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    d_body = d_cam @ R  # rows: R.T @ d
    origin = -R.T @ t
    lo, hi = BOX_CENTER_M - BOX_HALF_M, BOX_CENTER_M + BOX_HALF_M
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - origin) / d_body, (hi - origin) / d_body
    near = np.nanmax(np.minimum(t1, t2), axis=-1)
    far = np.nanmin(np.maximum(t1, t2), axis=-1)
    hit = (near <= far) & (near > 0)
    return np.where(hit, near, 0.0)  # d_cam has z = 1: the ray parameter is the depth


def _project(K: np.ndarray, R: np.ndarray, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    cam = points @ R.T + t
    return (cam[:, :2] / cam[:, 2:3]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]


def _crop_box(bbox: list[int] | None, size: tuple[int, int]) -> tuple[int, int, int, int]:
    w, h = size
    cx, cy = (
        ((bbox[0] + bbox[2] + 1) // 2, (bbox[1] + bbox[3] + 1) // 2) if bbox else (w // 2, h // 2)
    )
    x0 = int(np.clip(cx - CROP_SIDE_PX // 2, 0, w - CROP_SIDE_PX))
    y0 = int(np.clip(cy - CROP_SIDE_PX // 2, 0, h - CROP_SIDE_PX))
    return x0, y0, x0 + CROP_SIDE_PX, y0 + CROP_SIDE_PX


def _write_files(root: Path, index: int, arrays: dict, keys, crop: bool) -> dict:
    files = {}
    for key in keys:
        folder, suffix = FOLDERS[key]
        rel = f"{'crop/' if crop else ''}{folder}/frame_{index:06d}{suffix}"
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        if key == "depth_exr":
            write_exr(root / rel, {"Z": arrays[key].astype(np.float32)})
        else:
            write_png(root / rel, arrays[key])
        files[key] = rel
    return files


def _frame_arrays(depth: np.ndarray) -> dict:
    mask = depth > 0
    full_well = DETECTOR["bias_dn"] + DETECTOR["full_well_e"] / DETECTOR["conversion_gain_e_per_dn"]
    dn = (DETECTOR["bias_dn"] + mask * 30000.0 + (depth % 7.0) * 100).astype(np.uint16)
    return {
        "dn_png16": dn,
        "preview_png8": dn_preview_uint8(dn, DETECTOR["bias_dn"], full_well),
        "depth_exr": depth,
        "object_mask_png": mask.astype(np.uint8) * np.uint8(255),
        "part_mask_png16": mask.astype(np.uint16),
    }


def write_box_dataset(
    root: Path,
    keys: tuple[str, ...] = ALL_KEYS,
    crop: bool = False,
    full_frame: bool = True,
    complete: bool = True,
    centers_cam_m=CENTERS_CAM_M,
) -> Path:
    """Write the box dataset (one frame per box centre, 4 by default) into ``root``;
    returns root."""
    root.mkdir(parents=True)
    (root / "model").mkdir()
    mesh = box_mesh()
    write_obj(mesh, root / "model" / "target.obj")
    K = box_K()
    header = {
        "format": "satsight-dataset",
        "version": 3,
        "frame_count": len(centers_cam_m),
        "scenario": "box-fixture",
        "camera": {
            "focal_length_m": FOCAL_M,
            "pixel_pitch_m": PITCH_M,
            "image_size_px": list(SIZE_PX),
            "K": K.tolist(),
        },
        "sensor": {"detector": DETECTOR},
        "target": {
            "model_obj": "model/target.obj",
            "keypoints_body_m": mesh.box_keypoints_body_m.tolist(),
        },
    }
    (root / "manifest.json").write_text(json.dumps(header, indent=1))
    records = []
    for index in range(len(centers_cam_m)):
        R, t = box_pose(index, centers_cam_m)
        depth = ray_cast_box(R, t, K, SIZE_PX)
        arrays = _frame_arrays(depth)
        bbox = mask_bbox_xyxy_px(depth > 0)
        record = {
            "frame_index": index,
            "plan_index": index,
            "q_cam_from_body": canonical_quaternion(quaternion_from_matrix(R)).tolist(),
            "t_cam_from_body_m": t.tolist(),
            "K": K.tolist(),
            "image_size_px": list(SIZE_PX),
            "bbox_xyxy_px": bbox,
            "keypoints_px": _project(K, R, t, mesh.box_keypoints_body_m).tolist(),
            "object_pixel_count": int((depth > 0).sum()),
            "files": _write_files(root, index, arrays, keys, False) if full_frame else {},
        }
        if crop:
            x0, y0, x1, y1 = _crop_box(bbox, SIZE_PX)
            K_crop = K.copy()
            K_crop[0, 2] -= x0
            K_crop[1, 2] -= y0
            window = {k: a[y0:y1, x0:x1] for k, a in arrays.items()}
            record["crop"] = {
                "size_px": CROP_SIDE_PX,
                "box_xyxy_px": [x0, y0, x1, y1],
                "K": K_crop.tolist(),
                "bbox_xyxy_px": mask_bbox_xyxy_px(window["object_mask_png"] > 0),
                "keypoints_px": _project(K_crop, R, t, mesh.box_keypoints_body_m).tolist(),
                "files": _write_files(root, index, window, keys, True),
            }
        records.append(record)
    lines = "".join(json.dumps(r, separators=(",", ":")) + "\n" for r in records)
    (root / "journal.jsonl").write_text(lines)
    if complete:
        (root / "labels.json").write_text(json.dumps({**header, "frames": records}, indent=1))
        (root / "complete.json").write_text(json.dumps({"frame_count": len(records)}))
    return root


def tiny_scenario_dict() -> dict:
    """A 96 x 80 px scenario: three frames at 3-4 km and one at 50 km, 48 px crops."""
    return {
        "name": "export-tiny",
        "seed": 1,
        "camera": {"preset": "wide_field", "width_px": 96, "height_px": 80},
        "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
        "frames": [
            {"distance_km": 3.0, "azimuth_deg": 20.0, "elevation_deg": 25.0, "roll_deg": 0.0},
            {"distance_km": 3.5, "azimuth_deg": 110.0, "elevation_deg": -10.0, "roll_deg": 0.0},
            {"distance_km": 4.0, "azimuth_deg": 230.0, "elevation_deg": 40.0, "roll_deg": 0.0},
            {"distance_km": 50.0, "azimuth_deg": 300.0, "elevation_deg": 5.0, "roll_deg": 0.0},
        ],
        "render": {"bounces": 0},
        "outputs": {"crop": {"size_px": 48}},
    }


def render_tiny_dataset(root: Path) -> Path:
    """Render the tiny scenario into ``root`` (a complete dataset); return ``root``."""
    from satsight.config.scenario import parse_scenario
    from satsight.run.generation import generate_dataset

    generate_dataset(parse_scenario(tiny_scenario_dict(), "test"), root)
    assert (root / "manifest.json").is_file() and (root / "complete.json").is_file()
    return root
