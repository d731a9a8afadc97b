"""``satsight export --format bop``: layout, keys, poses, masks, depth and bad inputs.

The exported files are read back here by a reader written from the BOP documentation
(bop_toolkit docs/bop_datasets_format.md), not by the exporter's own code.
"""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.distance import pdist

from cli_runner import run_satsight
from export_datasets import (
    CENTERS_CAM_M,
    CROP_SIDE_PX,
    TRUNCATED_CENTERS_CAM_M,
    box_K,
    box_mesh,
    box_pose,
    ray_cast_box,
    render_tiny_dataset,
    write_box_dataset,
)
from satsight.dataset.export import export_dataset
from satsight.dataset.export.bop import bop_json_text, depth_scale_for
from satsight.dataset.export.splits import SplitRule, assign_splits
from satsight.dataset.image_files import read_png
from satsight.dataset.preview import dn_preview_uint8
from satsight.errors import SatsightError
from synthetic_datasets import (
    assert_peak_does_not_grow,
    export_memory_peaks,
)

RULE = SplitRule((0.5, 0.25, 0.25), seed=0)
CAMERA_KEYS = {"cx", "cy", "fx", "fy", "height", "width"}
SCENE_CAMERA_KEYS = {"cam_K", "depth_scale"}
SCENE_GT_KEYS = {"cam_R_m2c", "cam_t_m2c", "obj_id"}
GT_INFO_KEYS = {"bbox_obj", "bbox_visib", "px_count_all", "px_count_valid", "px_count_visib",
                "visib_fract"}  # fmt: skip
MODEL_INFO_KEYS = {"diameter", "min_x", "min_y", "min_z", "size_x", "size_y", "size_z"}
TARGET_KEYS = {"im_id", "inst_count", "obj_id", "scene_id"}


# --- a reader written from the BOP documentation -----------------------------------------
def load_json(path: Path) -> dict | list:
    document = json.loads(path.read_text(encoding="utf-8"))
    if isinstance(document, dict):
        return {int(k) if k.isdigit() else k: v for k, v in document.items()}
    return document


def read_bop_images(export: Path) -> dict[int, dict]:
    """frame (image id) -> {split, K, depth_scale, R, t_mm, info, gray, mask, mask_visib,
    depth_mm} over every split's scene 000000."""
    images = {}
    splits = ("train", "val", "test")
    for split_dir in sorted(p for p in export.iterdir() if p.is_dir() and p.name in splits):
        scene = split_dir / "000000"
        cameras = load_json(scene / "scene_camera.json")
        gts = load_json(scene / "scene_gt.json")
        infos = load_json(scene / "scene_gt_info.json")
        for im_id, camera in cameras.items():
            gt, info = gts[im_id][0], infos[im_id][0]
            depth_file = scene / "depth" / f"{im_id:06d}.png"
            images[im_id] = {
                "split": split_dir.name,
                "camera": camera,
                "gt": gt,
                "info": info,
                "K": np.array(camera["cam_K"]).reshape(3, 3),
                "R": np.array(gt["cam_R_m2c"]).reshape(3, 3),
                "t_mm": np.array(gt["cam_t_m2c"]),
                "gray": read_png(scene / "gray" / f"{im_id:06d}.png"),
                "mask": read_png(scene / "mask" / f"{im_id:06d}_000000.png") > 0,
                "mask_visib": read_png(scene / "mask_visib" / f"{im_id:06d}_000000.png") > 0,
                "depth_mm": read_png(depth_file).astype(np.float64) * camera["depth_scale"]
                if depth_file.is_file()
                else None,
            }
    return images


def project(K: np.ndarray, R: np.ndarray, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """BOP's P = K [R | t]: s [u, v, 1]^T = P [x, y, z, 1]^T, in bop_toolkit's pixel
    coordinates (the OpenGL window's: pixel (i, j) spans [i, i + 1) x [j, j + 1))."""
    p = (K @ (points @ R.T + t).T).T
    return p[:, :2] / p[:, 2:3]


def pixel_of(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cols, rows) of the pixels holding BOP pixel positions uv (N, 2)."""
    cols, rows = np.floor(uv).astype(int).T
    return cols, rows


#: satsight pixel position + this = the same point in bop_toolkit's pixel coordinates.
BOP_SHIFT_PX = 0.5
#: cam_K - this = satsight's K.
BOP_K_SHIFT = np.array([[0, 0, BOP_SHIFT_PX], [0, 0, BOP_SHIFT_PX], [0, 0, 0]])


# --- fixtures -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def box(tmp_path_factory) -> Path:
    return write_box_dataset(tmp_path_factory.mktemp("box") / "dataset", crop=True)


@pytest.fixture(scope="module")
def bop(box: Path) -> Path:
    out = box.parent / "bop"
    export_dataset(box, out, "bop", RULE)
    return out


@pytest.fixture(scope="module")
def labels(box: Path) -> dict:
    return json.loads((box / "labels.json").read_text())


# --- layout and keys ------------------------------------------------------------------------
def test_json_files_parse_and_have_exactly_the_bop_keys(bop: Path) -> None:
    assert set(load_json(bop / "camera.json")) == CAMERA_KEYS
    info = load_json(bop / "models" / "models_info.json")
    assert list(info) == [1] and set(info[1]) == MODEL_INFO_KEYS
    for split in ("train", "val", "test"):
        scene = bop / split / "000000"
        for entry in load_json(scene / "scene_camera.json").values():
            assert set(entry) == SCENE_CAMERA_KEYS and len(entry["cam_K"]) == 9
        for entries in load_json(scene / "scene_gt.json").values():
            assert len(entries) == 1 and set(entries[0]) == SCENE_GT_KEYS
            assert entries[0]["obj_id"] == 1
            assert len(entries[0]["cam_R_m2c"]) == 9 and len(entries[0]["cam_t_m2c"]) == 3
        for entries in load_json(scene / "scene_gt_info.json").values():
            assert len(entries) == 1 and set(entries[0]) == GT_INFO_KEYS
    targets19 = load_json(bop / "test_targets_bop19.json")
    for target in targets19:
        assert set(target) == TARGET_KEYS
    targets24 = load_json(bop / "test_targets_bop24.json")
    assert targets24 == [{"im_id": t["im_id"], "scene_id": 0} for t in targets19]
    for folder in ("models", "models_eval"):  # BOP's error functions read models_eval/
        assert (bop / folder / "obj_000001.ply").is_file()
        assert load_json(bop / folder / "models_info.json") == info


def test_json_layout_is_bop_toolkits(bop: Path) -> None:
    """One image id per line, keys in numeric order, values with sorted keys."""
    text = (bop / "train" / "000000" / "scene_gt.json").read_text()
    lines = text.split("\n")
    assert lines[0] == "{" and lines[-1] == "}"
    ids = [int(re.match(r'  "(\d+)": \[\{"cam_R_m2c": ', line).group(1)) for line in lines[1:-1]]
    assert ids == sorted(ids) and ids


def test_split_folders_hold_the_seeded_split(bop: Path, labels: dict) -> None:
    images = read_bop_images(bop)
    expected = assign_splits([f["frame_index"] for f in labels["frames"]], RULE)
    for split, frames in expected.items():
        assert sorted(i for i, im in images.items() if im["split"] == split) == frames
    record = json.loads((bop / "satsight_export.json").read_text())
    assert record["split"]["frames"] == expected and record["split"]["seed"] == 0


# --- poses, masks, boxes, depth -------------------------------------------------------------
def test_model_points_reproject_into_mask_visib(bop: Path, labels: dict) -> None:
    model = trimesh.load(bop / "models" / "obj_000001.ply", process=False)
    points_mm, _ = trimesh.sample.sample_surface(model, 4000, seed=1)
    keypoints_mm = np.array(labels["target"]["keypoints_body_m"]) * 1000.0
    images = read_bop_images(bop)
    assert len(images) == len(labels["frames"])
    for frame in labels["frames"]:
        im = images[frame["frame_index"]]
        # The label's keypoints, through the BOP pose, land on satsight's keypoints_px,
        # half a pixel on in the toolkit's pixel coordinates.
        uv = project(im["K"], im["R"], im["t_mm"], keypoints_mm)
        np.testing.assert_allclose(uv - BOP_SHIFT_PX, frame["keypoints_px"], rtol=0, atol=1e-6)
        mask = im["mask_visib"]
        assert np.array_equal(mask, im["mask"])  # one target, hidden only by itself
        assert mask.sum() == im["info"]["px_count_visib"] == frame["object_pixel_count"]
        if mask.sum() < 100:
            continue  # the 50 km frame: a few pixels, checked by its depth
        uv = project(im["K"], im["R"], im["t_mm"], points_mm)
        cols, rows = pixel_of(uv)
        inside = (cols >= 0) & (cols < mask.shape[1]) & (rows >= 0) & (rows < mask.shape[0])
        hits = np.zeros(len(uv), bool)
        hits[inside] = mask[rows[inside], cols[inside]]
        assert hits.mean() > 0.97, hits.mean()


def calc_box(mask: np.ndarray, x_offset: int = 0, y_offset: int = 0) -> list[int]:
    """bop_toolkit's calc_2d_bbox of a mask's pixels: [x, y, w, h], w = x_max - x_min."""
    rows, cols = np.nonzero(mask)
    rows, cols = rows - y_offset, cols - x_offset
    return [int(v) for v in (cols.min(), rows.min(), np.ptp(cols), np.ptp(rows))]


@pytest.mark.parametrize("centers", ["inside", "truncated"])
def test_gt_info_counts_the_whole_silhouette_as_calc_gt_info_does(
    bop: Path, tmp_path: Path, centers: str
) -> None:
    """The oracle is calc_gt_info.py's recipe with an exact ray caster: the model on a
    canvas three times the image, the image in its middle (cx + W, cy + H)."""
    centers_cam_m = CENTERS_CAM_M
    if centers == "truncated":
        centers_cam_m = TRUNCATED_CENTERS_CAM_M
        dataset = write_box_dataset(tmp_path / "d", centers_cam_m=centers_cam_m)
        bop = tmp_path / "bop"
        export_dataset(dataset, bop, "bop", RULE)
    truncated = 0
    for im_id, im in read_bop_images(bop).items():
        info = im["info"]
        assert info["bbox_visib"] == calc_box(im["mask_visib"])
        assert info["px_count_valid"] == im["mask"].sum()
        R, t = box_pose(im_id, centers_cam_m)
        height, width = im["mask"].shape
        K_large = box_K() + np.array([[0, 0, width], [0, 0, height], [0, 0, 0]])
        large = ray_cast_box(R, t, K_large, (3 * width, 3 * height)) > 0
        assert np.array_equal(large[height : 2 * height, width : 2 * width], im["mask"])
        assert info["px_count_all"] == large.sum()
        assert info["bbox_obj"] == calc_box(large, width, height)
        assert info["visib_fract"] == pytest.approx(im["mask"].sum() / large.sum(), rel=1e-12)
        truncated += info["px_count_all"] > info["px_count_visib"]
    assert truncated == (0 if centers == "inside" else len(centers_cam_m))


def test_depth_recovers_metres_within_the_quantum_at_50_km(bop: Path, labels: dict) -> None:
    images = read_bop_images(bop)
    for frame in labels["frames"]:
        im = images[frame["frame_index"]]
        R, t = box_pose(frame["frame_index"])
        size = (im["mask"].shape[1], im["mask"].shape[0])
        truth_m = ray_cast_box(R, t, im["K"] - BOP_K_SHIFT, size)
        scale = im["camera"]["depth_scale"]
        assert np.array_equal(im["depth_mm"] > 0, truth_m > 0)
        assert np.array_equal(truth_m > 0, im["mask"])
        error_m = np.abs(im["depth_mm"] / 1000.0 - truth_m)
        assert error_m.max() <= scale / 1000.0, (scale, error_m.max())
        far = frame["t_cam_from_body_m"][2] > 40e3
        assert scale == (1000.0 if far else 100.0)  # 50 km: 1 m steps; 4-5 km: 0.1 m
        if far:
            assert (truth_m > 49e3).sum() >= 3


@pytest.mark.parametrize(
    ("max_mm", "scale"),
    [(0.0, 1.0), (1.0, 0.01), (655.0, 0.01), (656.0, 0.02), (30e3, 0.5), (65534.0, 1.0),
     (65535.0, 2.0), (5e7, 1000.0), (3.2e8, 5000.0)],
)  # fmt: skip
def test_depth_scale_is_the_smallest_nice_value_that_fits(max_mm: float, scale: float) -> None:
    assert depth_scale_for(max_mm) == scale
    assert max_mm / scale < 65535


def test_toolkit_notes_register_the_export_with_its_own_numbers(box: Path, tmp_path) -> None:
    """BOP_TOOLKIT.md names the export as bop_toolkit can parse it (letters and digits of
    the final folder name), and its get_split_params branch runs and sets the export's
    values; the delta fits the 1 m depth steps at 50 km."""
    out = tmp_path / "Sat_export-2"
    export_dataset(box, out, "bop", RULE)
    notes = (out / "BOP_TOOLKIT.md").read_text()
    assert "partial" not in notes and "`$BOP_PATH/satexport2`" in notes
    snippet = re.search(r"```python\n(.*?)```", notes, re.S).group(1)
    branch = "if False:\n    pass\n" + textwrap.dedent(snippet)
    camera = load_json(out / "camera.json")
    for split, ids in (("train", [0]), ("val", [0]), ("test", [0])):
        p: dict = {}
        exec(branch, {}, {"p": p, "dataset_name": "satexport2", "split": split})
        assert p["scene_ids"] == ids
        assert p["im_size"] == (camera["width"], camera["height"])
        assert p["im_modalities"] == ["gray", "depth"]
        near_mm, far_mm = p["depth_range"]
        assert 3.9e6 < near_mm < far_mm < 5.01e7
    # Largest depth_scale 1000 mm (50 km): 2 x 1000 + 1e-6 x 5e7 = 2050 -> 5000 mm.
    assert '"satexport2": 5000,' in notes and 'p["delta"] = 5000' in notes


# --- the model --------------------------------------------------------------------------
def test_ply_model_is_in_millimetres_and_readable_by_trimesh(bop: Path) -> None:
    ply = bop / "models" / "obj_000001.ply"
    model = trimesh.load(ply, process=False)
    mesh = box_mesh()
    np.testing.assert_allclose(model.vertices, mesh.vertices_m * 1000.0, atol=1e-3)
    assert np.array_equal(model.faces, mesh.faces)
    header = ply.read_text().split("end_header")[0]
    assert "format ascii 1.0" in header and "property float nx" in header
    assert "property list uchar int vertex_indices" in header
    normals = np.loadtxt(ply.read_text().split("end_header\n")[1].splitlines()[:8])[:, 3:]
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    info = load_json(bop / "models" / "models_info.json")[1]
    vertices_mm = mesh.vertices_m * 1000.0
    assert info["diameter"] == pytest.approx(pdist(vertices_mm).max(), abs=1e-6)
    low, high = vertices_mm.min(axis=0), vertices_mm.max(axis=0)
    assert [info["min_x"], info["min_y"], info["min_z"]] == pytest.approx(low.tolist())
    assert [info["size_x"], info["size_y"], info["size_z"]] == pytest.approx((high - low).tolist())


# --- crops and output profiles --------------------------------------------------------------
def test_crop_export_uses_the_crop_intrinsics_and_images(box: Path, labels: dict) -> None:
    out = box.parent / "bop_crop"
    summary = export_dataset(box, out, "bop", RULE, crop=True)
    assert summary.crop
    images = read_bop_images(out)
    keypoints_mm = np.array(labels["target"]["keypoints_body_m"]) * 1000.0
    for frame in labels["frames"]:
        im = images[frame["frame_index"]]
        crop = frame["crop"]
        assert np.array_equal(im["K"], np.array(crop["K"]) + BOP_K_SHIFT)
        assert im["gray"].shape == im["mask"].shape == (CROP_SIDE_PX, CROP_SIDE_PX)
        uv = project(im["K"], im["R"], im["t_mm"], keypoints_mm)
        np.testing.assert_allclose(uv - BOP_SHIFT_PX, crop["keypoints_px"], rtol=0, atol=1e-6)
        x0, y0, x1, y1 = crop["box_xyxy_px"]
        truth = ray_cast_box(*box_pose(frame["frame_index"]), np.array(frame["K"]), (64, 48))
        assert np.array_equal(im["mask"], truth[y0:y1, x0:x1] > 0)


def test_crop_only_dataset_exports_its_crops(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", crop=True, full_frame=False)
    summary = export_dataset(dataset, tmp_path / "out", "bop", RULE)
    assert summary.crop
    assert set(load_json(tmp_path / "out" / "camera.json")) == CAMERA_KEYS
    gray = next((tmp_path / "out").glob("*/000000/gray/*.png"))
    assert read_png(gray).shape == (CROP_SIDE_PX, CROP_SIDE_PX)


def test_crop_flag_without_crops_is_refused(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d")
    with pytest.raises(SatsightError, match="has no crops"):
        export_dataset(dataset, tmp_path / "out", "bop", RULE, crop=True)
    assert not (tmp_path / "out").exists()


def test_lean_dataset_exports_dn_and_no_depth(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("dn_png16", "object_mask_png"))
    summary = export_dataset(dataset, tmp_path / "out", "bop", RULE)
    assert "no depth" in summary.line()
    for im_id, im in read_bop_images(tmp_path / "out").items():
        assert im["depth_mm"] is None and set(im["camera"]) == {"cam_K"}
        assert im["info"]["px_count_valid"] == 0
        dn = read_png(dataset / f"images/frame_{im_id:06d}.png")
        assert np.array_equal(im["gray"], dn - np.uint16(1000))  # DN above the bias
    assert not list((tmp_path / "out").glob("*/000000/depth"))
    notes = (tmp_path / "out" / "BOP_TOOLKIT.md").read_text()
    assert "No depth was exported" in notes


def test_preview_images_without_previews_stretch_the_dn(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("dn_png16", "object_mask_png"))
    export_dataset(dataset, tmp_path / "out", "bop", RULE, image="preview")
    for im_id, im in read_bop_images(tmp_path / "out").items():
        dn = read_png(dataset / f"images/frame_{im_id:06d}.png")
        assert np.array_equal(im["gray"], dn_preview_uint8(dn, 1000.0, 1000.0 + 350000 / 5.833))


def test_dataset_without_masks_is_refused_with_the_remedy(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("dn_png16", "depth_exr"))
    with pytest.raises(SatsightError, match=r"object_mask_png \(output 'masks'\)"):
        export_dataset(dataset, tmp_path / "out", "bop", RULE)
    assert not (tmp_path / "out").exists()


def test_dataset_with_previews_only_is_refused_with_both_remedies(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("preview_png8", "object_mask_png"))
    with pytest.raises(SatsightError, match=r"'dn' in outputs.files, or .* --image preview"):
        export_dataset(dataset, tmp_path / "out", "bop", RULE)
    assert not (tmp_path / "out").exists()
    export_dataset(dataset, tmp_path / "out", "bop", RULE, image="preview")
    gray = read_png(next((tmp_path / "out").glob("*/000000/gray/000000.png")))
    assert np.array_equal(gray, read_png(dataset / "previews" / "frame_000000.png"))


# --- the command line -----------------------------------------------------------------------
def _no_partial_folders(parent: Path) -> bool:
    return not [p for p in parent.iterdir() if ".partial-" in p.name]


def test_cli_writes_the_export_and_prints_one_line(box: Path) -> None:
    out = box.parent / "bop_cli"
    result = run_satsight(
        "export", str(box), "--format", "bop", "--out", str(out), "--split", "0.5,0.25,0.25",
        cwd=box.parent,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip().count("\n") == 0
    assert "exported 4 frames (train 2, val 1, test 1) as BOP" in result.stderr
    assert (out / "satsight_export.json").is_file()


@pytest.mark.parametrize("case", ["not_a_dataset", "incomplete", "bad_split", "out_not_empty"])
def test_cli_bad_inputs_exit_2_with_one_line_and_write_nothing(tmp_path: Path, case: str) -> None:
    dataset = tmp_path / "dataset"
    out = tmp_path / "export"
    split = "0.8,0.1,0.1"
    if case == "not_a_dataset":
        dataset.mkdir()
        (dataset / "notes.txt").write_text("hello")
        says = "is not a satsight dataset"
    elif case == "incomplete":
        write_box_dataset(dataset, complete=False)
        says = "incomplete dataset"
    elif case == "bad_split":
        write_box_dataset(dataset)
        split = "0.8,0.3,0.1"
        says = "must sum to 1"
    else:
        write_box_dataset(dataset)
        out.mkdir()
        (out / "keep.txt").write_text("mine")
        says = "not empty"
    result = run_satsight(
        "export", str(dataset), "--format", "bop", "--out", str(out), "--split", split,
        cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    message = result.stderr.strip()
    assert message.count("\n") == 0 and says in message, message
    assert "Traceback" not in result.stderr
    if case == "out_not_empty":
        assert [p.name for p in out.iterdir()] == ["keep.txt"]
    else:
        assert not out.exists()
    assert _no_partial_folders(tmp_path)


def test_overwrite_replaces_an_earlier_export_only(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d")
    out = tmp_path / "out"
    export_dataset(dataset, out, "bop", RULE)
    export_dataset(dataset, out, "bop", SplitRule((1.0, 0.0, 0.0)), overwrite=True)
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == [
        "models",
        "models_eval",
        "train",
    ]
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(SatsightError, match="replaces only earlier exports"):
        export_dataset(dataset, other, "bop", RULE, overwrite=True)
    with pytest.raises(SatsightError, match="overlaps the dataset"):
        export_dataset(dataset, dataset / "bop", "bop", RULE)
    assert _no_partial_folders(tmp_path)


# --- a rendered dataset -----------------------------------------------------------------
@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> Path:
    root = render_tiny_dataset(tmp_path_factory.mktemp("rendered") / "dataset")
    return root


def test_rendered_dataset_reprojects_into_its_masks(rendered: Path) -> None:
    out = rendered.parent / "bop"
    export_dataset(rendered, out, "bop", SplitRule((0.5, 0.25, 0.25), seed=2))
    labels = json.loads((rendered / "labels.json").read_text())
    model = trimesh.load(out / "models" / "obj_000001.ply", process=False)
    points_mm, _ = trimesh.sample.sample_surface(model, 4000, seed=1)
    keypoints_mm = np.array(labels["target"]["keypoints_body_m"]) * 1000.0
    images = read_bop_images(out)
    for frame in labels["frames"]:
        im = images[frame["frame_index"]]
        uv = project(im["K"], im["R"], im["t_mm"], keypoints_mm)
        np.testing.assert_allclose(uv - BOP_SHIFT_PX, frame["keypoints_px"], rtol=0, atol=1e-6)
        assert im["mask"].sum() == im["info"]["px_count_visib"] == frame["object_pixel_count"]
        scale = im["camera"]["depth_scale"]
        if frame["range_m"] > 40e3:
            assert scale == 1000.0
            depth_m = im["depth_mm"][im["mask"]] / 1000.0
            assert np.all(np.abs(depth_m - frame["range_m"]) < 20.0)  # the target's size
        elif im["mask"].sum() >= 100:
            uv = project(im["K"], im["R"], im["t_mm"], points_mm)
            cols, rows = pixel_of(uv)
            inside = (cols >= 0) & (cols < 96) & (rows >= 0) & (rows < 80)
            # Points inside the image (a truncated frame loses the rest): nearly all fall on
            # the mask; thin parts seen edge-on may miss every pixel centre.
            hits = im["mask"][rows[inside], cols[inside]]
            assert hits.mean() > 0.95, hits.mean()


def test_rendered_crops_export_with_their_intrinsics(rendered: Path) -> None:
    out = rendered.parent / "bop_crop"
    export_dataset(rendered, out, "bop", SplitRule((1.0, 0.0, 0.0)), crop=True)
    labels = json.loads((rendered / "labels.json").read_text())
    keypoints_mm = np.array(labels["target"]["keypoints_body_m"]) * 1000.0
    images = read_bop_images(out)
    for frame in labels["frames"]:
        im, crop = images[frame["frame_index"]], frame["crop"]
        assert im["gray"].shape == im["mask"].shape == im["depth_mm"].shape == (48, 48)
        uv = project(im["K"], im["R"], im["t_mm"], keypoints_mm)
        np.testing.assert_allclose(uv - BOP_SHIFT_PX, crop["keypoints_px"], rtol=0, atol=1e-6)
        assert im["mask"].sum() == im["info"]["px_count_visib"] == crop["object_pixel_count"]
        x0, y0, x1, y1 = crop["box_xyxy_px"]
        full = read_png(rendered / frame["files"]["object_mask_png"]) > 0
        assert np.array_equal(im["mask"], full[y0:y1, x0:x1])


# --- JSON written entry by entry, memory bounded ------------------------------------------
SCENE_FILES = ("scene_camera.json", "scene_gt.json", "scene_gt_info.json")


def assert_json_as_written_at_once(export: Path) -> int:
    """Every BOP JSON file of an export has the bytes the all-at-once writer
    (``bop_json_text`` of the whole dict or list) gives; returns the entries seen."""
    entries = 0
    for path in sorted(export.rglob("*.json")):
        if path.name == "satsight_export.json":
            continue
        text = path.read_text(encoding="utf-8")
        document = json.loads(text)
        if isinstance(document, dict):
            document = {int(k) if k.isdigit() else k: v for k, v in document.items()}
        assert text == bop_json_text(document), path
        entries += len(document) if path.name in SCENE_FILES else 0
    return entries


def test_streamed_json_equals_the_all_at_once_output(bop: Path, rendered: Path) -> None:
    assert assert_json_as_written_at_once(bop) == 3 * 4
    out = rendered.parent / "bop_json"
    export_dataset(rendered, out, "bop", SplitRule((0.5, 0.0, 0.5), seed=4), crop=True)
    assert assert_json_as_written_at_once(out) == 3 * 4
    assert (out / "test_targets_bop19.json").is_file()


def test_export_memory_does_not_grow_with_the_frame_count(
    datasets_with_files: tuple[Path, ...], tmp_path: Path
) -> None:
    """Datasets of N and 4N frames (previews and masks shared by all; records of 22 kB
    each as Python objects) export with the same memory peak, within a few bytes per
    frame: the split holds frame indices, records are read per split, and the scene JSON
    files are written entry by entry."""
    peaks = []
    for out, count, _, peak in export_memory_peaks(datasets_with_files, tmp_path, "bop"):
        assert assert_json_as_written_at_once(out) == 3 * count
        assert len(list((out / "train" / "000000" / "gray").iterdir())) == count * 8 // 10
        peaks.append(peak)
    assert_peak_does_not_grow(*peaks)
    assert peaks[-1].peak_bytes < peaks[-1].records_bytes / 10, peaks[-1]


def test_labels_only_dataset_is_refused_with_the_usual_error(
    labels_only_datasets: tuple[Path, ...], tmp_path: Path
) -> None:
    with pytest.raises(SatsightError, match="frame 0 has neither full-frame files nor a crop"):
        export_dataset(labels_only_datasets[0], tmp_path / "out", "bop", RULE)
    assert not (tmp_path / "out").exists()
