"""Viewpoints by direction and distance: closed forms of the camera pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.poses.views import View, direction_from_angles

ATOL = 1e-12
ATOL_POSITION_M = 1e-9  # camera positions up to 1e5 m, float64
CENTER_M = np.array([0.3, -1.2, 0.8])
CAMERA = PinholeCamera(focal_length_m=0.01, pixel_pitch_m=10e-6, width_px=8, height_px=6)


@pytest.mark.parametrize(
    ("azimuth_deg", "elevation_deg", "expected"),
    [
        (0.0, 0.0, (1.0, 0.0, 0.0)),
        (90.0, 0.0, (0.0, 1.0, 0.0)),
        (180.0, 0.0, (-1.0, 0.0, 0.0)),
        (-90.0, 0.0, (0.0, -1.0, 0.0)),
        (0.0, 90.0, (0.0, 0.0, 1.0)),
        (37.0, 90.0, (0.0, 0.0, 1.0)),
        (0.0, -90.0, (0.0, 0.0, -1.0)),
        (45.0, 0.0, (math.sqrt(0.5), math.sqrt(0.5), 0.0)),
        (0.0, 30.0, (math.sqrt(3.0) / 2.0, 0.0, 0.5)),
    ],
)
def test_direction_from_angles_closed_forms(azimuth_deg, elevation_deg, expected) -> None:
    d = direction_from_angles(math.radians(azimuth_deg), math.radians(elevation_deg))
    assert d.shape == (3,)
    np.testing.assert_allclose(d, expected, rtol=0, atol=ATOL)


@pytest.mark.parametrize(
    ("azimuth_deg", "elevation_deg", "roll_deg", "distance_m"),
    [
        (0.0, 0.0, 0.0, 800.0),
        (75.0, 10.0, 30.0, 1500.0),
        (140.0, 40.0, 0.0, 2500.0),
        (-30.0, -15.0, -90.0, 5000.0),
        (200.0, 90.0, 0.0, 1e5),
        (0.0, -90.0, 10.0, 12.0),
    ],
)
def test_camera_sits_at_distance_along_direction_and_looks_at_centre(
    azimuth_deg, elevation_deg, roll_deg, distance_m
) -> None:
    view = View(
        distance_m, math.radians(azimuth_deg), math.radians(elevation_deg), math.radians(roll_deg)
    )
    cam_from_body = view.cam_from_body(CENTER_M)
    direction = direction_from_angles(view.azimuth_rad, view.elevation_rad)
    # The camera centre (origin of the camera frame) in the body frame.
    camera_body = cam_from_body.inverse().apply(np.zeros(3))
    np.testing.assert_allclose(
        camera_body, CENTER_M + distance_m * direction, rtol=0, atol=ATOL_POSITION_M
    )
    # The target centre lies on the optical axis, at depth distance_m.
    center_cam = cam_from_body.apply(CENTER_M)
    np.testing.assert_allclose(center_cam, [0.0, 0.0, distance_m], rtol=0, atol=ATOL_POSITION_M)
    np.testing.assert_allclose(
        CAMERA.project(center_cam[None])[0], [CAMERA.cx_px, CAMERA.cy_px], rtol=0, atol=1e-9
    )
    # The boresight (+z_cam) points from the camera back along -direction.
    np.testing.assert_allclose(cam_from_body.R_a_from_b.T[:, 2], -direction, rtol=0, atol=ATOL)


@pytest.mark.parametrize("azimuth_deg", [0.0, 60.0, 135.0, 270.0])
def test_body_z_is_image_up_for_a_horizontal_view(azimuth_deg) -> None:
    view = View(1000.0, math.radians(azimuth_deg), 0.0)
    cam_from_body = view.cam_from_body(CENTER_M)
    np.testing.assert_allclose(cam_from_body.rotate([0.0, 0.0, 1.0]), [0, -1, 0], atol=ATOL)
    # A point above the centre projects above the principal point (smaller v).
    above = cam_from_body.apply(CENTER_M + np.array([0.0, 0.0, 1.0]))
    u, v = CAMERA.project(above[None])[0]
    assert u == pytest.approx(CAMERA.cx_px, abs=1e-9)
    assert v < CAMERA.cy_px


def test_view_from_plus_x_has_plus_y_to_the_right() -> None:
    """Looking along -x with +z up, the body +y axis points to the image right."""
    cam_from_body = View(1000.0, 0.0, 0.0).cam_from_body(np.zeros(3))
    np.testing.assert_allclose(
        cam_from_body.R_a_from_b, [[0, 1, 0], [0, 0, -1], [-1, 0, 0]], rtol=0, atol=ATOL
    )
    np.testing.assert_allclose(cam_from_body.t_a_from_b_m, [0, 0, 1000.0], atol=ATOL)


def test_view_from_the_pole_uses_body_x_as_up() -> None:
    cam_from_body = View(500.0, 0.0, math.radians(90.0)).cam_from_body(CENTER_M)
    np.testing.assert_allclose(cam_from_body.rotate([1.0, 0.0, 0.0]), [0, -1, 0], atol=ATOL)
    np.testing.assert_allclose(cam_from_body.rotate([0.0, 0.0, 1.0]), [0, 0, -1], atol=ATOL)


@pytest.mark.parametrize("roll_deg", [30.0, 90.0, -45.0, 180.0])
def test_roll_rotates_the_image_about_the_boresight(roll_deg) -> None:
    """A right-hand camera roll r about +z_cam turns the scene by -r in the image:
    body +z, image up (0, -1) at zero roll, becomes (-sin r, -cos r)."""
    roll = math.radians(roll_deg)
    base = View(1000.0, math.radians(20.0), math.radians(25.0))
    rolled = View(1000.0, base.azimuth_rad, base.elevation_rad, roll)
    up_cam = rolled.cam_from_body(CENTER_M).rotate([0.0, 0.0, 1.0])
    up_base = base.cam_from_body(CENTER_M).rotate([0.0, 0.0, 1.0])
    # Roll changes only the in-image components: the boresight component is the same.
    assert up_cam[2] == pytest.approx(up_base[2], abs=ATOL)
    scale = math.hypot(up_base[0], up_base[1])
    np.testing.assert_allclose(up_base[:2], [0.0, -scale], atol=ATOL)
    np.testing.assert_allclose(
        up_cam[:2], [-math.sin(roll) * scale, -math.cos(roll) * scale], rtol=0, atol=ATOL
    )
    # The camera does not move and still looks at the centre.
    np.testing.assert_allclose(
        rolled.cam_from_body(CENTER_M).apply(CENTER_M), [0, 0, 1000.0], atol=1e-9
    )
    np.testing.assert_allclose(
        rolled.cam_from_body(CENTER_M).inverse().t_a_from_b_m,
        base.cam_from_body(CENTER_M).inverse().t_a_from_b_m,
        atol=1e-9,
    )


def test_roll_of_90_degrees_puts_body_z_to_image_left() -> None:
    cam_from_body = View(1000.0, 0.0, 0.0, math.radians(90.0)).cam_from_body(np.zeros(3))
    np.testing.assert_allclose(cam_from_body.rotate([0.0, 0.0, 1.0]), [-1, 0, 0], atol=ATOL)


@pytest.mark.parametrize("distance_m", [0.0, -1.0, float("nan")])
def test_non_positive_distance_is_refused(distance_m) -> None:
    with pytest.raises(SatsightError, match="view distance must be positive"):
        View(distance_m, 0.0, 0.0)
