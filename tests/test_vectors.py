"""satsight.vectors: lengths, unit vectors and angles against closed forms; the look-at axes
against scipy's attitude solution."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.frames.rigid import look_at_cam_from_body
from satsight.poses.attitude import pointing_gcrs_from_cam
from satsight.vectors import LOOK_AT_AXES, angle_between_rad, look_at_axes, norm, unit

EPS = np.finfo(np.float64).eps


def test_norm_and_unit_of_known_vectors():
    v = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0]])
    np.testing.assert_array_equal(norm(v), [5.0, 2.0])
    np.testing.assert_allclose(unit(v), [[0.6, 0.8, 0.0], [0.0, 0.0, -1.0]], rtol=0, atol=EPS)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-6, 0.3, np.pi / 2, 2.5, np.pi - 1e-9, np.pi])
@pytest.mark.parametrize("dimension", [2, 3, 5])
def test_angle_between_rotated_unit_vectors_is_the_rotation_angle(angle, dimension):
    # u = e0, v = cos(a) e0 + sin(a) e1, both scaled: the angle is a to rounding, also near
    # 0 and pi, where arccos(u . v) would be off by ~sqrt(eps) ~ 1e-8 rad.
    u = np.zeros(dimension)
    v = np.zeros(dimension)
    u[0] = 2.5
    v[0], v[1] = 7.0 * np.cos(angle), 7.0 * np.sin(angle)
    assert angle_between_rad(u, v) == pytest.approx(angle, rel=8 * EPS, abs=8 * EPS)


def test_angle_between_rows_and_zero_vector():
    u = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    v = np.array([[0.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(angle_between_rad(u, v), [np.pi / 2, np.pi, 0.0], atol=4 * EPS)


# The camera axis (camera coordinates) that each reference_axis name puts the reference on.
_NAMED_AXIS_CAM = {"x": [1.0, 0.0, 0.0], "-x": [-1.0, 0.0, 0.0], "y": [0.0, 1.0, 0.0],
                   "-y": [0.0, -1.0, 0.0]}  # fmt: skip


@pytest.mark.parametrize("reference_axis", LOOK_AT_AXES)
def test_look_at_axes_match_scipys_two_vector_attitude(reference_axis):
    """Independent oracle: Wahba's problem with the boresight held exactly (infinite weight)
    and the reference as the secondary direction (scipy's align_vectors) gives the same
    R_world_from_cam, for random eyes, targets, references and rolls."""
    rng = np.random.default_rng(7)
    n = 64
    eye = rng.normal(size=(n, 3)) * 1e4
    target = rng.normal(size=(n, 3)) * 10.0
    reference = rng.normal(size=(n, 3))
    roll = rng.uniform(-np.pi, np.pi, size=n)
    R = look_at_axes(eye, target, reference, reference_axis, roll)
    assert R.shape == (n, 3, 3)
    for i in range(n):
        boresight = (target[i] - eye[i]) / np.linalg.norm(target[i] - eye[i])
        unrolled, _ = Rotation.align_vectors(
            [boresight, reference[i]], [[0.0, 0.0, 1.0], _NAMED_AXIS_CAM[reference_axis]],
            weights=[np.inf, 1.0],
        )  # fmt: skip
        # A right-hand roll about +z_cam turns the camera: R_world_from_cam Rz(roll).
        expected = unrolled.as_matrix() @ Rotation.from_rotvec([0.0, 0.0, roll[i]]).as_matrix()
        np.testing.assert_allclose(R[i], expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(R[i] @ R[i].T, np.eye(3), rtol=0, atol=8 * EPS)
        assert np.linalg.det(R[i]) == pytest.approx(1.0, abs=8 * EPS)


def test_the_camera_pose_and_the_inertial_pointing_are_one_construction():
    """look_at_cam_from_body (image up along the hint) and pointing_gcrs_from_cam with
    reference_axis "-y" give the same axes, bit for bit, including the fallbacks."""
    rng = np.random.default_rng(11)
    cases = [(rng.normal(size=3) * 50.0, rng.normal(size=3), rng.normal(size=3), rng.uniform(-3, 3))
             for _ in range(20)]  # fmt: skip
    cases += [(np.array([0.0, 0.0, 9.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.4)]
    for eye, target, hint, roll in cases:
        R_cam_from_body = look_at_cam_from_body(eye, target, hint, roll).R_a_from_b
        q = pointing_gcrs_from_cam(eye, target, hint, roll, reference_axis="-y")
        np.testing.assert_array_equal(
            R_cam_from_body.T, look_at_axes(eye, target, hint, "-y", roll)
        )
        np.testing.assert_allclose(matrix_from_quaternion(q), R_cam_from_body.T, atol=4 * EPS)


@pytest.mark.parametrize(
    ("eye", "reference", "used"),
    [
        ([0.0, 0.0, 10.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),  # zero: +Z, degenerate: +X
        ([10.0, 0.0, 0.0], [1.0, 1e-9, 0.0], [0.0, 0.0, 1.0]),  # 1e-9 rad from the boresight
        ([0.0, 0.0, -10.0], [0.0, 0.0, 5.0], [1.0, 0.0, 0.0]),  # along +-Z: +X
        ([3.0, 0.0, 0.0], [0.0, 2e-7, 1e-7], [0.0, 2.0, 1.0]),  # short, not parallel: itself
    ],
)
def test_look_at_falls_back_to_z_then_x_when_the_reference_cannot_fix_the_roll(
    eye, reference, used
):
    R = look_at_axes(eye, np.zeros(3), reference, "x")
    expected = look_at_axes(eye, np.zeros(3), used, "x")
    if np.linalg.norm(np.cross(used, eye)) < 1e-12:  # the first fallback is degenerate too
        expected = look_at_axes(eye, np.zeros(3), [1.0, 0.0, 0.0], "x")
    np.testing.assert_array_equal(R, expected)


def test_look_at_refuses_what_fixes_no_camera():
    with pytest.raises(SatsightError, match="coincides"):
        look_at_axes([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [0.0, 0.0, 1.0])
    with pytest.raises(SatsightError, match="reference_axis must be one of"):
        look_at_axes([1.0, 2.0, 3.0], np.zeros(3), [0.0, 0.0, 1.0], "up")
    with pytest.raises(SatsightError, match="eye_m must be finite"):
        look_at_axes([np.nan, 2.0, 3.0], np.zeros(3), [0.0, 0.0, 1.0])
    with pytest.raises(SatsightError, match="cannot pair these stacks"):
        look_at_axes(np.ones((2, 3)), np.zeros((3, 3)), [0.0, 0.0, 1.0])
    with pytest.raises(SatsightError, match="roll_rad must be a finite"):
        look_at_axes([1.0, 2.0, 3.0], np.zeros(3), [0.0, 0.0, 1.0], "x", np.inf)
