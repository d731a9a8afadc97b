"""``satsight export --format speedplus``: camera, labels, pose convention and pixels.

SPEED+'s projection is re-implemented here from its documented formula (SPEED+ tools:
speedplusbaseline src/utils/utils.py ``quat2dcm`` / ``project_keypoints``, ESA
speedplus-utils ``project``): p_cam = quat2dcm(q)^T p_body + r, x = p_cam / z,
OpenCV-style distortion with distCoeffs, u = fx_px x + cx, v = fy_px y + cy.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.io import loadmat

from export_datasets import (
    SIZE_PX,
    box_mesh,
    box_pose,
    render_tiny_dataset,
    write_box_dataset,
)
from satsight.dataset.export import export_dataset
from satsight.dataset.export.speedplus import json_text
from satsight.dataset.export.splits import SplitRule, assign_splits
from satsight.dataset.image_files import read_png
from satsight.dataset.preview import dn_preview_uint8
from satsight.errors import SatsightError

RULE = SplitRule((0.5, 0.25, 0.25), seed=5)
CAMERA_KEYS = {"cameraMatrix", "distCoeffs", "Nu", "Nv", "ppx", "ppy", "fx", "fy", "ccx", "ccy"}
LABEL_KEYS = {"filename", "q_vbs2tango_true", "r_Vo2To_vbs_true"}


def quat2dcm(q: np.ndarray) -> np.ndarray:
    """SPEED+'s direction cosine matrix of a scalar-first quaternion (as documented)."""
    q0, q1, q2, q3 = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array(
        [
            [2 * q0**2 - 1 + 2 * q1**2, 2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2)],
            [2 * (q1 * q2 - q0 * q3), 2 * q0**2 - 1 + 2 * q2**2, 2 * (q2 * q3 + q0 * q1)],
            [2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1), 2 * q0**2 - 1 + 2 * q3**2],
        ]
    )


def speedplus_project(q, r, camera: dict, points: np.ndarray) -> np.ndarray:
    """Pixels of body points (N, 3) with SPEED+'s formula and camera.json."""
    p = points @ quat2dcm(q) + np.asarray(r)  # rows: quat2dcm(q).T @ p + r
    x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    k1, k2, p1, p2, k3 = camera["distCoeffs"]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    K = np.array(camera["cameraMatrix"])
    return np.stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=-1)


def satsight_project(record: dict, points: np.ndarray) -> np.ndarray:
    """Pixels (satsight convention) of body points with satsight's labels."""
    from satsight.frames.quaternion import matrix_from_quaternion

    R = matrix_from_quaternion(np.array(record["q_cam_from_body"]))
    cam = points @ R.T + np.array(record["t_cam_from_body_m"])
    p = cam @ np.array(record["K"]).T
    return p[:, :2] / p[:, 2:3]


def read_labels(export: Path, domain: str = "synthetic") -> dict[str, list[dict]]:
    names = {"train": "train.json", "val": "validation.json", "test": "test.json"}
    return {s: json.loads((export / domain / n).read_text()) for s, n in names.items()}


@pytest.fixture(scope="module")
def box(tmp_path_factory) -> Path:
    return write_box_dataset(tmp_path_factory.mktemp("box") / "dataset", crop=True)


@pytest.fixture(scope="module")
def speedplus(box: Path) -> Path:
    out = box.parent / "speedplus"
    export_dataset(box, out, "speedplus", RULE)
    return out


@pytest.fixture(scope="module")
def frames(box: Path) -> dict[int, dict]:
    labels = json.loads((box / "labels.json").read_text())
    return {f["frame_index"]: f for f in labels["frames"]}


def test_speedplus_quaternion_convention_on_a_90_degree_turn() -> None:
    """A +90 deg turn about z (satsight: body x -> camera y) reads the same in SPEED+."""
    q = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])
    np.testing.assert_allclose(quat2dcm(q).T @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def test_camera_json_has_the_speedplus_keys_and_the_half_pixel_origin(speedplus: Path) -> None:
    camera = json.loads((speedplus / "camera.json").read_text())
    assert set(camera) == CAMERA_KEYS
    assert (camera["Nu"], camera["Nv"]) == SIZE_PX
    assert camera["distCoeffs"] == [0.0] * 5
    K = np.array(camera["cameraMatrix"])
    # satsight's principal point (W-1)/2, (H-1)/2 is SPEED+'s Nu/2, Nv/2.
    assert (camera["ccx"], camera["ccy"]) == (K[0, 2], K[1, 2]) == (SIZE_PX[0] / 2, SIZE_PX[1] / 2)
    assert camera["fx"] / camera["ppx"] == pytest.approx(K[0, 0], rel=1e-12)
    assert camera["fy"] / camera["ppy"] == pytest.approx(K[1, 1], rel=1e-12)
    assert camera["fx"] == 0.75 and camera["ppx"] == pytest.approx(10e-6, rel=1e-12)


def test_labels_follow_the_split_and_name_existing_images(
    speedplus: Path, frames: dict[int, dict]
) -> None:
    labels = read_labels(speedplus)
    expected = assign_splits(list(frames), RULE)
    for split, entries in labels.items():
        assert [int(e["filename"][3:9]) - 1 for e in entries] == expected[split]
        for entry in entries:
            assert set(entry) == LABEL_KEYS
            q = np.array(entry["q_vbs2tango_true"])
            assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12) and q[0] >= 0
            image = read_png(speedplus / "synthetic" / "images" / entry["filename"])
            assert image.dtype == np.uint16 and image.shape == (SIZE_PX[1], SIZE_PX[0])


def test_speedplus_projection_lands_on_satsight_pixels(
    speedplus: Path, frames: dict[int, dict], box: Path
) -> None:
    camera = json.loads((speedplus / "camera.json").read_text())
    vertices = box_mesh().vertices_m
    keypoints = np.array(
        json.loads((box / "manifest.json").read_text())["target"]["keypoints_body_m"]
    )
    for entries in read_labels(speedplus).values():
        for entry in entries:
            record = frames[int(entry["filename"][3:9]) - 1]
            q, r = entry["q_vbs2tango_true"], entry["r_Vo2To_vbs_true"]
            for points in (vertices, keypoints):
                uv_speedplus = speedplus_project(q, r, camera, points)
                uv_satsight = satsight_project(record, points)
                np.testing.assert_allclose(uv_speedplus, uv_satsight + 0.5, rtol=0, atol=1e-6)
            uv = speedplus_project(q, r, camera, keypoints)
            np.testing.assert_allclose(uv, np.array(record["keypoints_px"]) + 0.5, atol=1e-6)
            # The pose itself: same rotation and translation as satsight's.
            R, t = box_pose(record["frame_index"])
            np.testing.assert_allclose(quat2dcm(q).T, R, atol=1e-12)
            np.testing.assert_allclose(r, t, atol=1e-9)


def test_label_files_are_laid_out_as_written_at_once(speedplus: Path, tmp_path: Path) -> None:
    """The label files, written entry by entry, have the bytes of ``json_text`` of the whole
    list (empty lists included)."""
    for export in (speedplus, tmp_path / "all_train"):
        if not export.exists():
            export_dataset(speedplus.parent / "dataset", export, "speedplus", SplitRule((1, 0, 0)))
        for name in ("train.json", "validation.json", "test.json"):
            text = (export / "synthetic" / name).read_text(encoding="utf-8")
            assert text == json_text(json.loads(text)), name


def test_preview_mode_without_previews_exports_the_stretched_dn(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("dn_png16",))
    export_dataset(dataset, tmp_path / "out", "speedplus", RULE, domain="render", image="preview")
    for entries in read_labels(tmp_path / "out", "render").values():
        for entry in entries:
            index = int(entry["filename"][3:9]) - 1
            dn = read_png(dataset / f"images/frame_{index:06d}.png")
            image = read_png(tmp_path / "out" / "render" / "images" / entry["filename"])
            assert np.array_equal(image, dn_preview_uint8(dn, 1000.0, 1000.0 + 350000 / 5.833))


def test_crops_with_moving_windows_are_refused_with_the_remedy(box: Path, tmp_path: Path) -> None:
    with pytest.raises(SatsightError, match=r"one camera\.json.*--format bop"):
        export_dataset(box, tmp_path / "out", "speedplus", RULE, crop=True)
    assert not (tmp_path / "out").exists()


def test_dataset_without_images_is_refused(tmp_path: Path) -> None:
    dataset = write_box_dataset(tmp_path / "d", keys=("object_mask_png", "depth_exr"))
    with pytest.raises(SatsightError, match=r"needs dn_png16 \(output 'dn'\)"):
        export_dataset(dataset, tmp_path / "out", "speedplus", RULE)
    with pytest.raises(SatsightError, match="neither preview_png8 nor dn_png16"):
        export_dataset(dataset, tmp_path / "out", "speedplus", RULE, image="preview")
    assert not (tmp_path / "out").exists()


def test_bad_domain_is_refused(box: Path, tmp_path: Path) -> None:
    with pytest.raises(SatsightError, match="plain folder name"):
        export_dataset(box, tmp_path / "out", "speedplus", RULE, domain="../x")


def test_rendered_dataset_projects_through_speedplus(tmp_path: Path) -> None:
    root = render_tiny_dataset(tmp_path / "dataset")
    export_dataset(root, tmp_path / "out", "speedplus", SplitRule((1.0, 0.0, 0.0)))
    labels = json.loads((root / "labels.json").read_text())
    camera = json.loads((tmp_path / "out" / "camera.json").read_text())
    assert (camera["ccx"], camera["ccy"]) == (48.0, 40.0)
    model = trimesh.load(root / "model" / "target.obj", force="mesh", process=False)
    vertices = np.asarray(model.vertices)
    for entry, record in zip(read_labels(tmp_path / "out")["train"], labels["frames"], strict=True):
        q, r = entry["q_vbs2tango_true"], entry["r_Vo2To_vbs_true"]
        uv = speedplus_project(q, r, camera, vertices)
        np.testing.assert_allclose(uv, satsight_project(record, vertices) + 0.5, atol=1e-6)
        # The body keypoints, read as the SPEED+ baseline reads them (loadmat, transposed),
        # land on the frame's keypoints_px half a pixel on.
        tango = loadmat(tmp_path / "out" / "tangoPoints.mat")["tango3Dpoints"].T
        uv = speedplus_project(q, r, camera, tango)
        np.testing.assert_allclose(uv, np.array(record["keypoints_px"]) + 0.5, atol=1e-6)
    assert tango.shape == (11, 3)  # surface keypoints, the default
    document = json.loads((tmp_path / "out" / "keypoints.json").read_text())
    assert np.array_equal(document["keypoints_body_m"], tango)
    assert document["keypoints_body_m"] == labels["target"]["keypoints_body_m"]
    assert document["method"]["method"] == "surface"
