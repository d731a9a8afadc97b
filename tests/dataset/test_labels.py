"""Per-frame labels: the mask box on hand-made masks, and frame_labels closed forms."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from satsight.camera.pinhole import PinholeCamera
from satsight.dataset.labels import frame_labels, mask_bbox_xyxy_px
from satsight.lighting.light_field import SunLight
from satsight.poses.views import View
from satsight.render.buffers import RadianceImage
from satsight.scene.mesh import merge_parts

ATOL = 1e-9


# --- mask_bbox_xyxy_px ---------------------------------------------------------------------
def test_empty_mask_has_no_box() -> None:
    assert mask_bbox_xyxy_px(np.zeros((5, 7), dtype=bool)) is None
    assert mask_bbox_xyxy_px(np.zeros((0, 0), dtype=bool)) is None


def test_single_pixel_box_is_inclusive() -> None:
    mask = np.zeros((5, 7), dtype=bool)
    mask[3, 4] = True  # row 3 (y), column 4 (x)
    assert mask_bbox_xyxy_px(mask) == [4, 3, 4, 3]


def test_rectangle() -> None:
    mask = np.zeros((10, 12), dtype=bool)
    mask[2:6, 5:11] = True
    assert mask_bbox_xyxy_px(mask) == [5, 2, 10, 5]


def test_two_blobs_and_l_shape_give_the_enclosing_box() -> None:
    mask = np.zeros((20, 30), dtype=bool)
    mask[1, 28] = True
    mask[17:19, 3:5] = True
    assert mask_bbox_xyxy_px(mask) == [3, 1, 28, 18]
    l_shape = np.zeros((8, 8), dtype=bool)
    l_shape[2:7, 1] = True
    l_shape[6, 1:6] = True
    assert mask_bbox_xyxy_px(l_shape) == [1, 2, 5, 6]


def test_full_mask_and_non_bool_masks() -> None:
    assert mask_bbox_xyxy_px(np.ones((4, 9), dtype=bool)) == [0, 0, 8, 3]
    ids = np.zeros((6, 6), dtype=np.uint16)
    ids[1, 2], ids[4, 3] = 7, 300  # part ids count as "on target"
    assert mask_bbox_xyxy_px(ids) == [2, 1, 3, 4]


def test_box_values_are_python_ints_for_json() -> None:
    mask = np.zeros((4, 4), dtype=bool)
    mask[1:3, 2] = True
    box = mask_bbox_xyxy_px(mask)
    assert all(type(v) is int for v in box)
    assert json.loads(json.dumps(box)) == [2, 1, 2, 2]


# --- frame_labels ----------------------------------------------------------------------------
def _cube_mesh(center, side_m: float = 2.0):
    h = side_m / 2.0
    corners = np.array([[x, y, z] for z in (-h, h) for y in (-h, h) for x in (-h, h)])
    faces = np.array(
        [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
         [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
    )  # fmt: skip
    return merge_parts([("bus", "mli_gold", corners + np.asarray(center), faces)])


def _image(mask: np.ndarray) -> RadianceImage:
    h, w = mask.shape
    return RadianceImage(
        radiance_w_m2_sr=np.zeros((h, w, 3), np.float32),
        depth_m=np.where(mask, np.float32(1.0), np.float32(0.0)),
        part_id=mask.astype(np.uint16),
        normals_cam=np.zeros((h, w, 3), np.float32),
    )


def test_frame_labels_closed_forms() -> None:
    center = np.array([1.0, -2.0, 0.5])
    mesh = _cube_mesh(center)
    camera = PinholeCamera(focal_length_m=0.5, pixel_pitch_m=10e-6, width_px=40, height_px=30)
    # Camera 1 km along +x of the centre; Sun along +y: phase angle 90 degrees.
    cam_from_body = View(1000.0, 0.0, 0.0).cam_from_body(mesh.center_m)
    sun = SunLight(np.array([0.0, 2.0, 0.0]), 671.5)
    mask = np.zeros((30, 40), dtype=bool)
    mask[10:20, 5:12] = True
    labels = frame_labels(mesh, camera, cam_from_body, sun, _image(mask))

    assert labels["range_to_center_m"] == pytest.approx(1000.0, abs=ATOL)
    camera_body = center + np.array([1000.0, 0.0, 0.0])
    assert labels["range_m"] == pytest.approx(np.linalg.norm(camera_body), abs=ATOL)
    assert labels["phase_angle_deg"] == pytest.approx(90.0, abs=1e-9)
    # Sun +y body is image right (+x cam) for this view.
    np.testing.assert_allclose(labels["sun_direction_cam"], [1.0, 0.0, 0.0], atol=1e-12)
    assert labels["sun_irradiance_w_m2"] == 671.5
    np.testing.assert_allclose(labels["K"], camera.K, rtol=0, atol=0)
    assert labels["image_size_px"] == [40, 30]
    # Keypoints: the box centre (last) projects to the principal point at depth 1000 m;
    # corners with x = max are 1 m nearer the camera than the centre.
    np.testing.assert_allclose(labels["keypoints_px"][8], [19.5, 14.5], atol=1e-9)
    depths = np.array(labels["keypoints_depth_m"])
    assert len(labels["keypoints_px"]) == 9 and depths.shape == (9,)
    np.testing.assert_allclose(depths[[1, 3, 5, 7]], 999.0, atol=ATOL)
    np.testing.assert_allclose(depths[[0, 2, 4, 6]], 1001.0, atol=ATOL)
    assert depths[8] == pytest.approx(1000.0, abs=ATOL)
    # Corner 3 (x max, y max, z min): right of and below the centre; f/p = 50000 px.
    u, v = labels["keypoints_px"][3]
    assert u == pytest.approx(19.5 + 50000.0 * 1.0 / 999.0, abs=1e-9)
    assert v == pytest.approx(14.5 + 50000.0 * 1.0 / 999.0, abs=1e-9)
    # From the mask.
    assert labels["bbox_xyxy_px"] == [5, 10, 11, 19]
    assert labels["object_pixel_count"] == 70
    assert labels["visible_pixel_fraction"] == 70 / 1200
    assert labels["truncated"] is False
    # The pose is stored scalar-first with qw >= 0 and matches the transform.
    q = np.array(labels["q_cam_from_body"])
    assert q[0] >= 0 and np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(labels["t_cam_from_body_m"], cam_from_body.t_a_from_b_m)
    # No footprint grid in this image: the label says its pixels are pixel-centre values.
    assert labels["target_footprint"] == {"integrated": False}
    json.dumps(labels)  # JSON-ready


def test_frame_labels_carry_the_footprint_of_a_small_target() -> None:
    """The renderer's footprint record (integrated box, sub-pixel flag, grid) reaches the
    frame's labels as it is."""
    mesh = _cube_mesh(np.zeros(3))
    camera = PinholeCamera(focal_length_m=0.5, pixel_pitch_m=10e-6, width_px=40, height_px=30)
    cam_from_body = View(1000.0, 0.0, 0.0).cam_from_body(mesh.center_m)
    footprint = {
        "integrated": True,
        "projected_box_xyxy_px": [19.0, 14.0, 20.0, 15.0],
        "sub_pixel": False,
        "sample_spacing_px": [0.01, 0.01],
        "sample_count": 10000,
    }
    image = dataclasses.replace(_image(np.zeros((30, 40), dtype=bool)), footprint=footprint)
    labels = frame_labels(mesh, camera, cam_from_body, SunLight(np.ones(3), 1.0), image)
    assert labels["target_footprint"] == footprint
    assert labels["object_pixel_count"] == 0


@pytest.mark.parametrize(
    ("row", "col", "truncated"),
    [(0, 5, True), (29, 5, True), (5, 0, True), (5, 39, True), (1, 1, False), (28, 38, False)],
)
def test_truncated_when_the_mask_touches_the_border(row, col, truncated) -> None:
    mesh = _cube_mesh(np.zeros(3))
    camera = PinholeCamera(focal_length_m=0.5, pixel_pitch_m=10e-6, width_px=40, height_px=30)
    mask = np.zeros((30, 40), dtype=bool)
    mask[row, col] = True
    cam_from_body = View(100.0, math.radians(30.0), math.radians(10.0)).cam_from_body(np.zeros(3))
    labels = frame_labels(mesh, camera, cam_from_body, SunLight(np.ones(3), 1.0), _image(mask))
    assert labels["truncated"] is truncated
    assert labels["bbox_xyxy_px"] == [col, row, col, row]
    assert labels["object_pixel_count"] == 1


def test_empty_frame_labels() -> None:
    mesh = _cube_mesh(np.zeros(3))
    camera = PinholeCamera(focal_length_m=0.5, pixel_pitch_m=10e-6, width_px=8, height_px=6)
    cam_from_body = View(100.0, 0.0, 0.0).cam_from_body(np.zeros(3))
    labels = frame_labels(
        mesh, camera, cam_from_body, SunLight(np.ones(3), 1.0), _image(np.zeros((6, 8), bool))
    )
    assert labels["bbox_xyxy_px"] is None
    assert labels["object_pixel_count"] == 0
    assert labels["visible_pixel_fraction"] == 0.0
    assert labels["truncated"] is False
