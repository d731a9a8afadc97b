"""Target attitude laws and camera pointing: closed forms and independent constructions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from satsight.ephemeris.orbits import (
    MU_EARTH_M3_S2,
    OrbitalElements,
    orbital_period_s,
    propagate,
    state_from_elements,
)
from satsight.errors import SatsightError
from satsight.frames.orbital import (
    inertial_from_relative_rtn,
    lvlh_from_inertial,
    rtn_from_inertial,
)
from satsight.frames.quaternion import (
    angle_between_quaternions_rad,
    matrix_from_quaternion,
    quaternion_conjugate,
    quaternion_from_axis_angle,
    quaternion_multiply,
    rotate_vectors,
)
from satsight.frames.rigid import look_at_cam_from_body
from satsight.poses.attitude import (
    REFERENCE_AXES,
    ROLL_POLICIES,
    cam_from_body,
    camera_reference,
    inertial_attitude,
    lvlh_fixed_attitude,
    pointing_gcrs_from_cam,
    spinning_attitude,
)
from satsight.poses.relative_motion import fly_around_initial_state, hover_initial_state

# Directions and rotations built from unit vectors: round-off is a few 1e-16.
DIRECTION_ATOL = 1e-12
ANGLE_ATOL_RAD = 1e-12
# Positions of at most a few hundred m rotated by such matrices.
POSITION_ATOL_M = 1e-10

A_M = 7000e3
N_RAD_S = math.sqrt(MU_EARTH_M3_S2 / A_M**3)
PERIOD_S = orbital_period_s(A_M)
TARGET = OrbitalElements(A_M, 0.0, math.radians(51.6), 0.3, 0.0, 0.5)

RNG = np.random.default_rng(20240611)


def random_unit_quaternions(n: int) -> np.ndarray:
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def assert_canonical_unit(q: np.ndarray) -> None:
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    assert np.all(q[..., 0] >= 0.0)


def test_lvlh_fixed_attitude_puts_the_body_axes_on_the_lvlh_axes() -> None:
    r0, v0 = state_from_elements(TARGET)
    r, v = propagate(r0, v0, np.linspace(0.0, 3000.0, 13), j2=True, method="dop853")
    q = lvlh_fixed_attitude(r, v)
    assert q.shape == (13, 4)
    assert_canonical_unit(q)
    # Columns of R_gcrs_from_body are the body axes in GCRS: with no offset, the LVLH axes.
    np.testing.assert_allclose(
        matrix_from_quaternion(q), np.swapaxes(lvlh_from_inertial(r, v), 1, 2), atol=DIRECTION_ATOL
    )
    # A fixed offset composes on the right: x_gcrs = R_gcrs_from_lvlh R_lvlh_from_body x_body.
    q_offset = quaternion_from_axis_angle([0.3, -1.0, 0.2], 0.8)
    q_off = lvlh_fixed_attitude(r, v, q_offset)
    expected = np.swapaxes(lvlh_from_inertial(r, v), 1, 2) @ matrix_from_quaternion(q_offset)
    np.testing.assert_allclose(matrix_from_quaternion(q_off), expected, atol=DIRECTION_ATOL)
    # A single state gives a single quaternion.
    assert lvlh_fixed_attitude(r[0], v[0]).shape == (4,)
    with pytest.raises(SatsightError, match="unit quaternions"):
        lvlh_fixed_attitude(r, v, [2.0, 0.0, 0.0, 0.0])


def test_lvlh_fixed_body_turns_once_per_orbit_about_the_orbit_normal() -> None:
    r0, v0 = state_from_elements(TARGET)
    t = np.linspace(0.0, PERIOD_S, 25)
    r, v = propagate(r0, v0, t, j2=False, method="dop853")
    q = lvlh_fixed_attitude(r, v)
    turned = angle_between_quaternions_rad(q[0], q)
    expected = np.minimum(N_RAD_S * t, 2.0 * math.pi - N_RAD_S * t)
    np.testing.assert_allclose(turned, expected, atol=1e-9)
    # The body y axis (LVLH y = -orbit normal) keeps its inertial direction.
    y_gcrs = rotate_vectors(q, np.array([0.0, 1.0, 0.0]))
    normal = np.cross(r0, v0) / np.linalg.norm(np.cross(r0, v0))
    np.testing.assert_allclose(y_gcrs, np.broadcast_to(-normal, y_gcrs.shape), atol=DIRECTION_ATOL)


def test_inertial_attitude_repeats_the_canonical_quaternion() -> None:
    q = np.array([-0.5, 0.5, -0.5, 0.5])
    stack = inertial_attitude(q, 4)
    np.testing.assert_array_equal(stack, np.tile(-q, (4, 1)))
    with pytest.raises(SatsightError, match="positive whole number"):
        inertial_attitude(q, 0)
    with pytest.raises(SatsightError, match="one quaternion"):
        inertial_attitude(np.tile(q, (2, 1)), 2)


def test_spinning_attitude_solves_the_kinematic_equation() -> None:
    q0 = random_unit_quaternions(1)[0]
    omega = np.array([0.05, -0.12, 0.07])
    t = np.linspace(0.0, 60.0, 31)
    h_s = 1e-3
    q = spinning_attitude(q0, omega, t)
    q_plus = spinning_attitude(q0, omega, t + h_s)
    q_minus = spinning_attitude(q0, omega, t - h_s)
    assert_canonical_unit(q)
    # Align the signs of the neighbours (each row is canonicalised on its own).
    q_plus *= np.sign(np.sum(q_plus * q, axis=1, keepdims=True))
    q_minus *= np.sign(np.sum(q_minus * q, axis=1, keepdims=True))
    derivative = (q_plus - q_minus) / (2.0 * h_s)
    omega_pure = np.concatenate([[0.0], omega])
    expected = 0.5 * quaternion_multiply(q, np.broadcast_to(omega_pure, q.shape))
    # Central difference error h^2 |omega|^3 / 48 ~ 1e-10; round-off eps / h ~ 1e-13.
    np.testing.assert_allclose(derivative, expected, atol=1e-9)
    # It starts at q0 and turns by |omega| t (an attitude angle, folded into [0, pi]).
    np.testing.assert_allclose(q[0] * np.sign(q[0] @ q0), q0, atol=DIRECTION_ATOL)
    turned_rad = np.mod(np.linalg.norm(omega) * t, 2.0 * math.pi)
    np.testing.assert_allclose(
        angle_between_quaternions_rad(q0, q),
        np.minimum(turned_rad, 2.0 * math.pi - turned_rad),
        atol=ANGLE_ATOL_RAD,
    )
    # Independent construction: R(t) = R(q0) exp([omega t]x), via scipy's rotation vector.
    expected_R = matrix_from_quaternion(q0) @ Rotation.from_rotvec(t[:, None] * omega).as_matrix()
    np.testing.assert_allclose(matrix_from_quaternion(q), expected_R, atol=DIRECTION_ATOL)


def test_axis_aligned_spin_keeps_that_body_axis_fixed_inertially() -> None:
    q0 = random_unit_quaternions(1)[0]
    t = np.linspace(0.0, 100.0, 41)
    for axis in range(3):
        omega = np.zeros(3)
        omega[axis] = -0.3
        q = spinning_attitude(q0, omega, t)
        e = np.zeros(3)
        e[axis] = 1.0
        spin_axis_gcrs = rotate_vectors(q, e)
        np.testing.assert_allclose(
            spin_axis_gcrs, np.broadcast_to(rotate_vectors(q0, e), (t.size, 3)), atol=DIRECTION_ATOL
        )
        # The other axes do turn: after half a turn they are reversed.
        q_half = spinning_attitude(q0, omega, [math.pi / 0.3])[0]
        other = np.roll(e, 1)
        np.testing.assert_allclose(
            rotate_vectors(q_half, other), -rotate_vectors(q0, other), atol=DIRECTION_ATOL
        )
    no_spin = spinning_attitude(q0, np.zeros(3), t)
    np.testing.assert_allclose(
        no_spin, np.tile(q0 * np.sign(q0[0]), (t.size, 1)), atol=DIRECTION_ATOL
    )


def image_components(q_gcrs_from_cam: np.ndarray, vectors_gcrs: np.ndarray) -> np.ndarray:
    return rotate_vectors(quaternion_conjugate(q_gcrs_from_cam), vectors_gcrs)


def test_pointing_puts_the_target_on_the_boresight_and_the_reference_on_its_axis() -> None:
    n = 64
    observer = RNG.normal(size=(n, 3)) * 7e6
    target = observer + RNG.normal(size=(n, 3)) * 1e3
    reference = RNG.normal(size=(n, 3))
    line_of_sight = (target - observer) / np.linalg.norm(target - observer, axis=1, keepdims=True)
    axis_index = {"x": (0, 1.0), "-x": (0, -1.0), "y": (1, 1.0), "-y": (1, -1.0)}
    for name in REFERENCE_AXES:
        q = pointing_gcrs_from_cam(observer, target, reference, reference_axis=name)
        assert q.shape == (n, 4)
        assert_canonical_unit(q)
        boresight = image_components(q, line_of_sight)
        np.testing.assert_allclose(
            boresight, np.broadcast_to([0.0, 0.0, 1.0], (n, 3)), atol=DIRECTION_ATOL
        )
        ref_cam = image_components(q, reference)
        index, sign = axis_index[name]
        assert np.all(sign * ref_cam[:, index] > 0.0)
        np.testing.assert_allclose(ref_cam[:, 1 - index], 0.0, atol=DIRECTION_ATOL)


def test_roll_turns_the_camera_about_its_boresight() -> None:
    n = 16
    observer = RNG.normal(size=(n, 3)) * 1e3
    target = RNG.normal(size=(n, 3)) * 1e3
    reference = RNG.normal(size=(n, 3))
    roll = RNG.uniform(-math.pi, math.pi, size=n)
    q0 = pointing_gcrs_from_cam(observer, target, reference)
    q = pointing_gcrs_from_cam(observer, target, reference, roll_rad=roll)
    # Right-hand roll about +z_cam: q_gcrs_from_cam' = q_gcrs_from_cam * rot(z, roll).
    rolled = quaternion_multiply(q0, quaternion_from_axis_angle([0.0, 0.0, 1.0], roll))
    np.testing.assert_allclose(angle_between_quaternions_rad(rolled, q), 0.0, atol=ANGLE_ATOL_RAD)
    np.testing.assert_allclose(
        angle_between_quaternions_rad(q0, q), np.abs(roll), atol=ANGLE_ATOL_RAD
    )
    # The scene turns the other way in the image: the reference now sits at angle -roll
    # from +x (angles measured from +x towards +y, image down).
    ref_cam = image_components(q, reference)
    angle = np.arctan2(ref_cam[:, 1], ref_cam[:, 0])
    np.testing.assert_allclose(np.angle(np.exp(1j * (angle + roll))), 0.0, atol=ANGLE_ATOL_RAD)


def test_pointing_with_image_up_matches_the_look_at_camera() -> None:
    for _ in range(20):
        camera = RNG.normal(size=3) * 50.0
        target = RNG.normal(size=3)
        up = RNG.normal(size=3)
        roll = float(RNG.uniform(-3.0, 3.0))
        pose = look_at_cam_from_body(camera, target, up, roll)
        q = pointing_gcrs_from_cam(camera, target, up, roll_rad=roll, reference_axis="-y")
        assert q.shape == (4,)
        np.testing.assert_allclose(
            matrix_from_quaternion(quaternion_conjugate(q)), pose.R_a_from_b, atol=DIRECTION_ATOL
        )
        # The same pose label, with the "body" frame taken as the inertial frame itself.
        q_cam_from_body, t = cam_from_body(q, [1.0, 0.0, 0.0, 0.0], camera, np.zeros(3))
        np.testing.assert_allclose(
            matrix_from_quaternion(q_cam_from_body), pose.R_a_from_b, atol=DIRECTION_ATOL
        )
        np.testing.assert_allclose(t, pose.t_a_from_b_m, atol=POSITION_ATOL_M)


def test_reference_along_the_boresight_falls_back_deterministically() -> None:
    observer = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    target = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0]])
    # Row 0: reference along the boresight -> inertial +Z; row 1: boresight along -Z, and +Z
    # is parallel too -> inertial +X.
    q = pointing_gcrs_from_cam(observer, target, target)
    expected = pointing_gcrs_from_cam(observer, target, [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(q, expected, atol=DIRECTION_ATOL)
    # Rows far from degenerate are unaffected by the fallback of other rows.
    mixed = pointing_gcrs_from_cam(observer, target, [[3.0, 4.0, 0.0], [0.0, 1.0, 0.0]])
    alone = pointing_gcrs_from_cam(observer[1], target[1], [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(mixed[1], alone)
    np.testing.assert_allclose(mixed[0], expected[0], atol=DIRECTION_ATOL)


def test_pointing_rejects_bad_input() -> None:
    with pytest.raises(SatsightError, match="coincides"):
        pointing_gcrs_from_cam(np.ones(3), np.ones(3), [0.0, 0.0, 1.0])
    with pytest.raises(SatsightError, match="reference_axis"):
        pointing_gcrs_from_cam(np.zeros(3), np.ones(3), [0.0, 0.0, 1.0], reference_axis="up")
    with pytest.raises(SatsightError, match="non-zero"):
        pointing_gcrs_from_cam(np.zeros(3), np.ones(3), np.zeros(3))
    with pytest.raises(SatsightError, match="cannot pair"):
        pointing_gcrs_from_cam(np.zeros((2, 3)), np.ones((3, 3)), [0.0, 0.0, 1.0])


def test_camera_reference_policies() -> None:
    r0, v0 = state_from_elements(TARGET)
    r, v = propagate(r0, v0, np.linspace(0.0, 1000.0, 5), j2=True, method="dop853")
    rtn = rtn_from_inertial(r, v)
    reference, axis = camera_reference("orbit_normal", r, v)
    assert axis == "x"
    np.testing.assert_array_equal(reference, rtn[:, 2])
    reference, axis = camera_reference("zenith_up", r, v)
    assert axis == "-y"
    np.testing.assert_array_equal(reference, rtn[:, 0])
    assert ROLL_POLICIES == ("orbit_normal", "zenith_up")
    with pytest.raises(SatsightError, match="roll policy"):
        camera_reference("sun_up", r, v)


def test_paper_initial_configuration_on_the_v_bar() -> None:
    # Observer on the target's V-bar (linear hover, both in the orbit plane), camera on the
    # target. The paper: "optical axis (Z) initially along -T, X along N": observer ahead.
    r_t, v_t = state_from_elements(TARGET)
    R_rtn = rtn_from_inertial(r_t, v_t)
    radial, along, normal = R_rtn
    for sign, boresight, y_axis in ((1, -along, -radial), (-1, along, radial)):
        rho, rho_dot = hover_initial_state(1000.0, along_track_sign=sign)
        r_o, v_o = inertial_from_relative_rtn(r_t, v_t, rho, rho_dot)
        reference, axis = camera_reference("orbit_normal", r_o, v_o)
        q = pointing_gcrs_from_cam(r_o, r_t, reference, reference_axis=axis)
        R_gcrs_from_cam = matrix_from_quaternion(q)
        np.testing.assert_allclose(R_gcrs_from_cam[:, 2], boresight, atol=DIRECTION_ATOL)
        np.testing.assert_allclose(R_gcrs_from_cam[:, 0], normal, atol=DIRECTION_ATOL)
        np.testing.assert_allclose(R_gcrs_from_cam[:, 1], y_axis, atol=DIRECTION_ATOL)
        # zenith_up agrees ahead of the target (Earth at the bottom either way) and is rolled
        # by half a turn behind it.
        reference, axis = camera_reference("zenith_up", r_o, v_o)
        q_up = pointing_gcrs_from_cam(r_o, r_t, reference, reference_axis=axis)
        expected_angle = 0.0 if sign > 0 else math.pi
        assert angle_between_quaternions_rad(q, q_up) == pytest.approx(expected_angle, abs=1e-9)


def test_cam_from_body_maps_body_points_like_the_inertial_chain() -> None:
    n = 12
    observer = RNG.normal(size=(n, 3)) * 1e3
    origin = RNG.normal(size=(n, 3)) * 10.0
    aim = origin + RNG.normal(size=(n, 3))
    q_gcrs_from_cam = pointing_gcrs_from_cam(observer, aim, RNG.normal(size=(n, 3)))
    q_gcrs_from_body = random_unit_quaternions(n)
    q, t = cam_from_body(q_gcrs_from_cam, q_gcrs_from_body, observer, origin)
    assert q.shape == (n, 4) and t.shape == (n, 3)
    assert_canonical_unit(q)
    points_body = RNG.normal(size=(n, 3)) * 5.0
    # Independent chain with matrices: body -> GCRS (about the origin) -> camera.
    points_gcrs = origin + np.einsum(
        "nij,nj->ni", matrix_from_quaternion(q_gcrs_from_body), points_body
    )
    R_cam_from_gcrs = np.swapaxes(matrix_from_quaternion(q_gcrs_from_cam), 1, 2)
    expected = np.einsum("nij,nj->ni", R_cam_from_gcrs, points_gcrs - observer)
    got = np.einsum("nij,nj->ni", matrix_from_quaternion(q), points_body) + t
    np.testing.assert_allclose(got, expected, atol=1e-12 * 1e4)  # |x| up to ~ 5e3 m


def test_body_origin_is_at_the_image_centre_along_a_fly_around() -> None:
    # An LVLH-fixed target on its orbit, an observer on a 1 km fly-around, the camera on the
    # target's body origin with the orbit_normal roll policy.
    r_t0, v_t0 = state_from_elements(TARGET)
    t = np.linspace(0.0, PERIOD_S, 37)
    r_t, v_t = propagate(r_t0, v_t0, t, j2=True, method="rk4", step_s=10.0)
    rho0, rho_dot0 = fly_around_initial_state(1000.0, N_RAD_S)
    r_o0, v_o0 = inertial_from_relative_rtn(r_t0, v_t0, rho0, rho_dot0)
    r_o, v_o = propagate(r_o0, v_o0, t, j2=True, method="rk4", step_s=10.0)
    reference, axis = camera_reference("orbit_normal", r_o, v_o)
    q_gcrs_from_cam = pointing_gcrs_from_cam(r_o, r_t, reference, reference_axis=axis)
    q, t_cam = cam_from_body(q_gcrs_from_cam, lvlh_fixed_attitude(r_t, v_t), r_o, r_t)
    distance = np.linalg.norm(r_t - r_o, axis=1)
    np.testing.assert_allclose(t_cam[:, :2] / t_cam[:, 2:], 0.0, atol=DIRECTION_ATOL)
    np.testing.assert_allclose(t_cam[:, 2], distance, rtol=1e-12)
    assert_canonical_unit(q)
