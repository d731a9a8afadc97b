"""Rigid transforms x_a = R_a_from_b @ x_b + t_a_from_b_m, and the look-at camera pose."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion, quaternion_from_axis_angle
from satsight.frames.rigid import RigidTransform, look_at_cam_from_body
from tolerances import ONE_NM

ATOL = 1e-12  # rotations and unit vectors
# canonical_quaternion writes a |qw| <= 1e-12 (too small to decide the sign) as |qw|
# (satsight.frames.quaternion): the rotation it gives back can differ by up to 2 x 2e-12 per
# matrix element (2 qw qz terms), near 180-degree turns.
CANONICAL_MATRIX_ATOL = 4e-12 + ATOL
PROPERTY = settings(max_examples=50, deadline=None)

_component = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_subnormal=False)
_coordinate_m = st.floats(min_value=-100.0, max_value=100.0, allow_nan=False, allow_subnormal=False)


@st.composite
def points_m(draw: st.DrawFn) -> np.ndarray:
    return np.array([draw(_coordinate_m) for _ in range(3)])


@st.composite
def directions(draw: st.DrawFn) -> np.ndarray:
    v = np.array([draw(_component) for _ in range(3)])
    assume(np.linalg.norm(v) > 1e-2)
    return v / np.linalg.norm(v)


@st.composite
def transforms(draw: st.DrawFn) -> RigidTransform:
    q = np.array([draw(_component) for _ in range(4)])
    assume(np.linalg.norm(q) > 1e-3)
    return RigidTransform.from_quaternion(q, draw(points_m()))


def R_z(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# --- RigidTransform ----------------------------------------------------------------------


@PROPERTY
@given(transforms(), points_m())
def test_apply_is_rotation_then_translation(a_from_b: RigidTransform, x_b: np.ndarray) -> None:
    expected = a_from_b.R_a_from_b @ x_b + a_from_b.t_a_from_b_m
    np.testing.assert_allclose(a_from_b.apply(x_b), expected, atol=ONE_NM)
    # The origin of b lands on t_a_from_b_m.
    np.testing.assert_allclose(a_from_b.apply(np.zeros(3)), a_from_b.t_a_from_b_m, atol=0)


@PROPERTY
@given(transforms(), transforms(), points_m())
def test_composition_names_cancel(
    a_from_b: RigidTransform, b_from_c: RigidTransform, x_c: np.ndarray
) -> None:
    a_from_c = a_from_b @ b_from_c
    np.testing.assert_allclose(
        a_from_c.apply(x_c), a_from_b.apply(b_from_c.apply(x_c)), atol=ONE_NM
    )
    np.testing.assert_allclose(
        a_from_c.R_a_from_b, a_from_b.R_a_from_b @ b_from_c.R_a_from_b, atol=ATOL
    )


@PROPERTY
@given(transforms(), transforms(), transforms())
def test_composition_is_associative(
    a_from_b: RigidTransform, b_from_c: RigidTransform, c_from_d: RigidTransform
) -> None:
    left = (a_from_b @ b_from_c) @ c_from_d
    right = a_from_b @ (b_from_c @ c_from_d)
    np.testing.assert_allclose(left.as_matrix(), right.as_matrix(), atol=ONE_NM)


@PROPERTY
@given(transforms(), points_m())
def test_inverse_round_trips(a_from_b: RigidTransform, x_b: np.ndarray) -> None:
    b_from_a = a_from_b.inverse()
    np.testing.assert_allclose(b_from_a.apply(a_from_b.apply(x_b)), x_b, atol=ONE_NM)
    np.testing.assert_allclose((a_from_b @ b_from_a).as_matrix(), np.eye(4), atol=ONE_NM)
    np.testing.assert_allclose((b_from_a @ a_from_b).as_matrix(), np.eye(4), atol=ONE_NM)
    np.testing.assert_allclose(b_from_a.inverse().as_matrix(), a_from_b.as_matrix(), atol=ONE_NM)
    # The origin of a, seen from b, is -R^T t.
    np.testing.assert_allclose(
        b_from_a.t_a_from_b_m, -a_from_b.R_a_from_b.T @ a_from_b.t_a_from_b_m, atol=ONE_NM
    )


@PROPERTY
@given(transforms(), transforms())
def test_inverse_of_composition_reverses_order(
    a_from_b: RigidTransform, b_from_c: RigidTransform
) -> None:
    c_from_a = (a_from_b @ b_from_c).inverse()
    np.testing.assert_allclose(
        c_from_a.as_matrix(), (b_from_c.inverse() @ a_from_b.inverse()).as_matrix(), atol=ONE_NM
    )


@PROPERTY
@given(transforms(), transforms(), points_m())
def test_as_matrix_is_the_homogeneous_form(
    a_from_b: RigidTransform, b_from_c: RigidTransform, x_b: np.ndarray
) -> None:
    M = a_from_b.as_matrix()
    assert M.shape == (4, 4)
    np.testing.assert_array_equal(M[3], [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose((M @ np.append(x_b, 1.0))[:3], a_from_b.apply(x_b), atol=ONE_NM)
    np.testing.assert_allclose(
        (a_from_b @ b_from_c).as_matrix(), M @ b_from_c.as_matrix(), atol=ONE_NM
    )


@PROPERTY
@given(transforms(), directions())
def test_rotate_ignores_translation(a_from_b: RigidTransform, d_b: np.ndarray) -> None:
    np.testing.assert_allclose(a_from_b.rotate(d_b), a_from_b.R_a_from_b @ d_b, atol=ATOL)
    np.testing.assert_allclose(
        a_from_b.rotate(d_b), a_from_b.apply(d_b) - a_from_b.apply(np.zeros(3)), atol=ONE_NM
    )


@PROPERTY
@given(transforms())
def test_quaternion_property_round_trips(a_from_b: RigidTransform) -> None:
    q = a_from_b.q_a_from_b
    assert q.shape == (4,)
    assert q[0] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=ATOL)
    R = a_from_b.R_a_from_b
    np.testing.assert_allclose(matrix_from_quaternion(q), R, atol=CANONICAL_MATRIX_ATOL)
    rebuilt = RigidTransform.from_quaternion(q, a_from_b.t_a_from_b_m)
    np.testing.assert_allclose(
        rebuilt.as_matrix(), a_from_b.as_matrix(), atol=CANONICAL_MATRIX_ATOL
    )
    # Same as SciPy's reading of the matrix (up to the sign SciPy picks).
    scipy_q = Rotation.from_matrix(a_from_b.R_a_from_b).as_quat(scalar_first=True)
    assert min(np.abs(q - scipy_q).max(), np.abs(q + scipy_q).max()) <= ATOL


def test_from_quaternion_90_degrees_about_z() -> None:
    q = quaternion_from_axis_angle([0.0, 0.0, 1.0], math.pi / 2)
    a_from_b = RigidTransform.from_quaternion(q, [1.0, 2.0, 3.0])
    # x_b = (1, 0, 0) turns to (0, 1, 0), then shifts by t.
    np.testing.assert_allclose(a_from_b.apply([1.0, 0.0, 0.0]), [1.0, 3.0, 3.0], atol=ATOL)


def test_identity_and_batches() -> None:
    identity = RigidTransform.identity()
    np.testing.assert_array_equal(identity.as_matrix(), np.eye(4))
    np.testing.assert_array_equal(identity.q_a_from_b, [1.0, 0.0, 0.0, 0.0])
    a_from_b = RigidTransform(R_z(0.3), [1.0, -2.0, 0.5])
    x_b = np.random.default_rng(5).normal(size=(4, 7, 3))
    batch = a_from_b.apply(x_b)
    assert batch.shape == (4, 7, 3)
    np.testing.assert_allclose(batch[2, 3], a_from_b.apply(x_b[2, 3]), atol=ATOL)
    assert a_from_b.rotate(x_b).shape == (4, 7, 3)


@pytest.mark.parametrize(
    ("R", "t"),
    [
        (np.eye(3).ravel(), np.zeros(3)),  # flattened matrix
        (np.eye(4), np.zeros(3)),
        (np.eye(3), np.zeros(4)),
        (np.eye(3), np.zeros((1, 3))),
    ],
)
def test_bad_shapes_raise(R: np.ndarray, t: np.ndarray) -> None:
    with pytest.raises(SatsightError, match="shape"):
        RigidTransform(R, t)


@pytest.mark.parametrize(
    "R",
    [2.0 * np.eye(3), np.diag([1.0, 1.0, -1.0]), np.zeros((3, 3)), np.full((3, 3), np.nan)],
)
def test_non_rotation_raises(R: np.ndarray) -> None:
    with pytest.raises(SatsightError, match="not a proper rotation"):
        RigidTransform(R, np.zeros(3))


def test_non_finite_translation_raises() -> None:
    with pytest.raises(SatsightError, match="finite"):
        RigidTransform(np.eye(3), [0.0, np.inf, 0.0])


# --- look_at_cam_from_body ---------------------------------------------------------------


@PROPERTY
@given(points_m(), points_m(), directions(), st.floats(min_value=-math.pi, max_value=math.pi))
def test_look_at_puts_the_target_on_the_optical_axis(
    camera_body_m: np.ndarray, target_body_m: np.ndarray, up_body: np.ndarray, roll_rad: float
) -> None:
    distance_m = float(np.linalg.norm(target_body_m - camera_body_m))
    assume(distance_m > 1e-3)
    cam_from_body = look_at_cam_from_body(camera_body_m, target_body_m, up_body, roll_rad)
    R = cam_from_body.R_a_from_b
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=ATOL)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=ATOL)
    np.testing.assert_allclose(
        cam_from_body.apply(target_body_m), [0.0, 0.0, distance_m], atol=ONE_NM
    )
    # The camera sits at the camera-frame origin.
    np.testing.assert_allclose(cam_from_body.apply(camera_body_m), np.zeros(3), atol=ONE_NM)


@PROPERTY
@given(points_m(), points_m(), directions())
def test_look_at_up_hint_is_image_up(
    camera_body_m: np.ndarray, target_body_m: np.ndarray, up_body: np.ndarray
) -> None:
    boresight = target_body_m - camera_body_m
    assume(np.linalg.norm(boresight) > 1e-3)
    boresight /= np.linalg.norm(boresight)
    up_perp = up_body - (up_body @ boresight) * boresight
    assume(np.linalg.norm(up_perp) > 1e-2)  # hint well away from the boresight
    cam_from_body = look_at_cam_from_body(camera_body_m, target_body_m, up_body)
    up_cam = cam_from_body.rotate(up_body)
    # The hint lies in the camera's y-z plane (no sideways component) and points to -y.
    assert abs(up_cam[0]) <= 1e-9
    assert up_cam[1] < 0.0
    # Image up (-y of the camera, in body axes) is the hint projected on the image plane.
    minus_y_body = -cam_from_body.R_a_from_b[1]
    np.testing.assert_allclose(minus_y_body, up_perp / np.linalg.norm(up_perp), atol=1e-9)


def test_look_at_known_pose() -> None:
    # Camera on -x looking at the origin, body +z up: boresight = +x_body, image up = +z_body,
    # so image right (+x_cam) is -y_body (right-handed: x_cam = y_cam cross z_cam).
    cam_from_body = look_at_cam_from_body([-10.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    R_body_from_cam = cam_from_body.R_a_from_b.T
    np.testing.assert_allclose(R_body_from_cam[:, 0], [0.0, -1.0, 0.0], atol=ATOL)
    np.testing.assert_allclose(R_body_from_cam[:, 1], [0.0, 0.0, -1.0], atol=ATOL)
    np.testing.assert_allclose(R_body_from_cam[:, 2], [1.0, 0.0, 0.0], atol=ATOL)
    np.testing.assert_allclose(cam_from_body.t_a_from_b_m, [0.0, 0.0, 10.0], atol=ATOL)
    # A point above the target (+z_body) appears above the image centre (y_cam < 0).
    assert cam_from_body.apply([0.0, 0.0, 1.0])[1] < 0.0


@PROPERTY
@given(points_m(), directions(), directions(), st.floats(min_value=-math.pi, max_value=math.pi))
def test_roll_turns_the_camera_about_its_boresight(
    camera_body_m: np.ndarray, boresight: np.ndarray, up_body: np.ndarray, roll_rad: float
) -> None:
    assume(np.linalg.norm(np.cross(up_body, boresight)) > 1e-2)
    target_body_m = camera_body_m + 50.0 * boresight
    unrolled = look_at_cam_from_body(camera_body_m, target_body_m, up_body, 0.0)
    rolled = look_at_cam_from_body(camera_body_m, target_body_m, up_body, roll_rad)
    # The camera body turns by +roll (right hand about +z_cam), so
    # R_body_from_cam_rolled = R_body_from_cam @ R_z(roll), i.e. cam axes x' = cos x + sin y.
    np.testing.assert_allclose(rolled.R_a_from_b, R_z(roll_rad).T @ unrolled.R_a_from_b, atol=1e-9)
    # The boresight and the camera position do not change.
    np.testing.assert_allclose(rolled.R_a_from_b[2], unrolled.R_a_from_b[2], atol=ATOL)
    np.testing.assert_allclose(rolled.apply(target_body_m), [0.0, 0.0, 50.0], atol=ONE_NM)


def test_roll_of_90_degrees_in_the_stated_sense() -> None:
    args = ([-10.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    unrolled = look_at_cam_from_body(*args)
    rolled = look_at_cam_from_body(*args, roll_rad=math.pi / 2)
    # +90 deg about +z_cam carries the camera's +x to where its +y was (image down, -z_body).
    np.testing.assert_allclose(rolled.R_a_from_b[0], unrolled.R_a_from_b[1], atol=ATOL)
    np.testing.assert_allclose(rolled.R_a_from_b[1], -unrolled.R_a_from_b[0], atol=ATOL)
    # A point above the target (+z_body) now appears on the image's left (x_cam < 0):
    # the scene turns by -roll in the image.
    above = rolled.apply([0.0, 0.0, 1.0])
    assert above[0] == pytest.approx(-1.0, abs=ATOL)
    assert above[1] == pytest.approx(0.0, abs=ATOL)


@pytest.mark.parametrize(
    ("camera_body_m", "up_body"),
    [
        ([0.0, 0.0, 10.0], [0.0, 0.0, 1.0]),  # hint anti-parallel to the boresight (-z)
        ([0.0, 0.0, -10.0], [0.0, 0.0, 1.0]),  # hint parallel to the boresight
        ([0.0, 0.0, 10.0], [0.0, 0.0, 0.0]),  # no hint at all
        ([0.0, 0.0, 10.0], [0.0, 0.0, -3.0]),  # the fallback z axis is degenerate too
        ([5.0, 0.0, 0.0], [1.0, 1e-9, 0.0]),  # hint within 1e-9 rad of the boresight
        ([-4.0, -1e-5, 0.0], [1.0, 0.0, 0.0]),  # 2.5e-6 rad: used, but ill-conditioned
    ],
)
def test_look_at_degenerate_up_hint_still_gives_a_valid_pose(
    camera_body_m: list[float], up_body: list[float]
) -> None:
    target = np.array([0.0, 0.0, 0.0])
    cam_from_body = look_at_cam_from_body(camera_body_m, target, up_body)
    R = cam_from_body.R_a_from_b
    assert np.all(np.isfinite(R))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=ATOL)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=ATOL)
    distance_m = float(np.linalg.norm(camera_body_m))
    np.testing.assert_allclose(cam_from_body.apply(target), [0.0, 0.0, distance_m], atol=ONE_NM)


def test_look_at_coincident_camera_and_target_raises() -> None:
    with pytest.raises(SatsightError, match="coincides"):
        look_at_cam_from_body([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])


@pytest.mark.parametrize(
    "kwargs",
    [
        {"camera_position_body_m": [np.nan, 0.0, 0.0]},
        {"target_point_body_m": [0.0, 0.0]},
        {"up_hint_body": [0.0, np.inf, 1.0]},
        {"roll_rad": math.nan},
    ],
)
def test_look_at_bad_inputs_raise(kwargs: dict) -> None:
    args = {
        "camera_position_body_m": [0.0, 0.0, -10.0],
        "target_point_body_m": [0.0, 0.0, 0.0],
        "up_hint_body": [0.0, 1.0, 0.0],
        "roll_rad": 0.0,
    }
    args.update(kwargs)
    with pytest.raises(SatsightError, match="finite"):
        look_at_cam_from_body(**args)
