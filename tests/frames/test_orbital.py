"""Orbit-attached frames: RTN (rows R, T, N), CCSDS LVLH, and relative motion in RTN."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

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
    relative_rtn,
    rtn_from_inertial,
)

ATOL = 1e-12
PROPERTY = settings(max_examples=100, deadline=None)

_position_m = st.floats(-5e7, 5e7, allow_nan=False, allow_subnormal=False)
_velocity_m_s = st.floats(-1e4, 1e4, allow_nan=False, allow_subnormal=False)


@st.composite
def states(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    r = np.array([draw(_position_m) for _ in range(3)])
    v = np.array([draw(_velocity_m_s) for _ in range(3)])
    r_norm, v_norm = np.linalg.norm(r), np.linalg.norm(v)
    assume(r_norm > 1e3 and v_norm > 1.0)
    assume(np.linalg.norm(np.cross(r, v)) > 1e-3 * r_norm * v_norm)
    return r, v


def assert_proper_rotation(R: np.ndarray) -> None:
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=ATOL)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=ATOL)


@PROPERTY
@given(states())
def test_rtn_is_a_right_handed_rotation_with_the_defined_axes(state) -> None:
    r, v = state
    R = rtn_from_inertial(r, v)
    assert_proper_rotation(R)
    np.testing.assert_allclose(R[0], r / np.linalg.norm(r), atol=ATOL)
    h = np.cross(r, v)
    np.testing.assert_allclose(R[2], h / np.linalg.norm(h), atol=ATOL)
    np.testing.assert_allclose(R[1], np.cross(R[2], R[0]), atol=ATOL)
    # v lies in the R-T plane, with a positive along-track component.
    rotated_v = R @ v
    assert abs(rotated_v[2]) <= 1e-9 * np.linalg.norm(v)
    assert rotated_v[1] > 0.0


@PROPERTY
@given(states())
def test_lvlh_is_a_right_handed_rotation_in_the_ccsds_convention(state) -> None:
    r, v = state
    L = lvlh_from_inertial(r, v)
    assert_proper_rotation(L)
    R = rtn_from_inertial(r, v)
    np.testing.assert_allclose(L[2], -r / np.linalg.norm(r), atol=ATOL)  # nadir
    np.testing.assert_allclose(L, np.stack([R[1], -R[2], -R[0]]), atol=ATOL)


def test_frames_are_vectorised_over_states() -> None:
    el = OrbitalElements.from_km_deg(7000.0, 0.1, 30.0, 10.0, 20.0, 0.0)
    r0, v0 = state_from_elements(el)
    r, v = propagate(r0, v0, np.linspace(0.0, 3000.0, 7), j2=False, method="dop853")
    for function in (rtn_from_inertial, lvlh_from_inertial):
        stacked = function(r, v)
        assert stacked.shape == (7, 3, 3)
        for k in range(7):
            np.testing.assert_array_equal(stacked[k], function(r[k], v[k]))


def test_circular_orbit_along_track_and_lvlh_x_follow_the_velocity() -> None:
    el = OrbitalElements.from_km_deg(7000.0, 0.0, 51.6, 30.0, 0.0, 0.0)
    r0, v0 = state_from_elements(el)
    r, v = propagate(r0, v0, np.linspace(0.0, 5000.0, 11), j2=False, method="dop853")
    v_hat = v / np.linalg.norm(v, axis=1, keepdims=True)
    np.testing.assert_allclose(rtn_from_inertial(r, v)[:, 1], v_hat, atol=1e-9)
    np.testing.assert_allclose(lvlh_from_inertial(r, v)[:, 0], v_hat, atol=1e-9)


def test_same_circular_orbit_gives_constant_along_track_offset_at_rest() -> None:
    # Chaser 0.01 deg behind the target on the same circular orbit: in the rotating RTN frame
    # it sits still at rho = a (cos d - 1, -sin d, 0) (1.2 km behind, 0.1 m below).
    a = 7000e3
    delta = math.radians(0.01)
    target = OrbitalElements(a, 0.0, 0.9, 0.3, 0.0, 0.5)
    chaser = OrbitalElements(a, 0.0, 0.9, 0.3, 0.0, 0.5 - delta)
    times = np.linspace(0.0, orbital_period_s(a), 9)
    r_t, v_t = propagate(*state_from_elements(target), times, j2=False, method="dop853")
    r_c, v_c = propagate(*state_from_elements(chaser), times, j2=False, method="dop853")
    rho, rho_dot = relative_rtn(r_t, v_t, r_c, v_c)
    expected = a * np.array([math.cos(delta) - 1.0, -math.sin(delta), 0.0])
    np.testing.assert_allclose(rho, np.broadcast_to(expected, rho.shape), atol=1e-3)
    np.testing.assert_allclose(rho_dot, 0.0, atol=1e-6)
    # Without the omega x rho term the inertial velocity difference is omega |rho| ~ 1.3 m/s.
    omega = math.sqrt(MU_EARTH_M3_S2 / a**3)
    inertial_difference = np.linalg.norm(v_c - v_t, axis=1)
    np.testing.assert_allclose(inertial_difference, omega * np.linalg.norm(expected), rtol=1e-6)


def test_relative_rtn_of_a_radial_offset_with_equal_velocity() -> None:
    # A chaser 100 m above the target with the same inertial velocity drifts backwards in
    # RTN at omega * 100 m: the rotating frame moves along-track faster at larger radius.
    r_t = np.array([7000e3, 0.0, 0.0])
    v_t = np.array([0.0, math.sqrt(MU_EARTH_M3_S2 / 7000e3), 0.0])
    rho, rho_dot = relative_rtn(r_t, v_t, r_t + np.array([100.0, 0.0, 0.0]), v_t)
    omega = v_t[1] / 7000e3
    np.testing.assert_allclose(rho, [100.0, 0.0, 0.0], atol=ATOL)
    np.testing.assert_allclose(rho_dot, [0.0, -omega * 100.0, 0.0], atol=ATOL)


def test_degenerate_or_malformed_states_are_rejected() -> None:
    r = np.array([7e6, 0.0, 0.0])
    with pytest.raises(SatsightError, match="parallel"):
        rtn_from_inertial(r, np.array([10.0, 0.0, 0.0]))
    with pytest.raises(SatsightError, match="parallel"):
        lvlh_from_inertial(np.zeros(3), np.array([0.0, 7.5e3, 0.0]))
    with pytest.raises(SatsightError, match="shape"):
        rtn_from_inertial(r, np.zeros((2, 3)))
    with pytest.raises(SatsightError, match="finite"):
        rtn_from_inertial(r, np.array([0.0, np.inf, 0.0]))
    with pytest.raises(SatsightError, match="same shape"):
        relative_rtn(r, [0.0, 7.5e3, 0.0], np.zeros((2, 3)), np.zeros((2, 3)))


@PROPERTY
@given(states(), states())
def test_inertial_from_relative_rtn_inverts_relative_rtn(target, chaser) -> None:
    r_t, v_t = target
    r_c, v_c = chaser
    rho, rho_dot = relative_rtn(r_t, v_t, r_c, v_c)
    r_back, v_back = inertial_from_relative_rtn(r_t, v_t, rho, rho_dot)
    # Relative to the largest magnitude involved: the differences are formed from both states.
    position_scale_m = max(np.linalg.norm(r_t), np.linalg.norm(r_c))
    velocity_scale_m_s = max(
        np.linalg.norm(v_t),
        np.linalg.norm(v_c),
        np.linalg.norm(v_t) / np.linalg.norm(r_t) * np.linalg.norm(r_c - r_t),
    )
    np.testing.assert_allclose(r_back, r_c, rtol=0.0, atol=1e-9 * position_scale_m)
    np.testing.assert_allclose(v_back, v_c, rtol=0.0, atol=1e-9 * velocity_scale_m_s)
    # And the other way round, on a stack of states.
    r_stack, v_stack = np.stack([r_t, r_c]), np.stack([v_t, v_c])
    rho_stack, rho_dot_stack = np.stack([rho, -rho]), np.stack([rho_dot, 2.0 * rho_dot])
    r_out, v_out = inertial_from_relative_rtn(r_stack, v_stack, rho_stack, rho_dot_stack)
    rho_back, rho_dot_back = relative_rtn(r_stack, v_stack, r_out, v_out)
    np.testing.assert_allclose(rho_back, rho_stack, rtol=0.0, atol=1e-9 * position_scale_m)
    np.testing.assert_allclose(
        rho_dot_back, rho_dot_stack, rtol=0.0, atol=1e-9 * 2.0 * velocity_scale_m_s
    )


def test_inertial_from_relative_rtn_rejects_mismatched_shapes() -> None:
    r = np.array([7e6, 0.0, 0.0])
    v = np.array([0.0, 7.5e3, 0.0])
    with pytest.raises(SatsightError, match="same shape"):
        inertial_from_relative_rtn(r, v, np.zeros((2, 3)), np.zeros((2, 3)))
