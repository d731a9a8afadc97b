"""Clohessy-Wiltshire relative motion and the natural and guided trajectories built on it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.orbits import (
    J2,
    MU_EARTH_M3_S2,
    OrbitalElements,
    orbital_period_s,
    propagate,
    state_from_elements,
)
from satsight.errors import SatsightError
from satsight.frames.orbital import inertial_from_relative_rtn, relative_rtn
from satsight.poses.relative_motion import (
    cw_propagate,
    fly_around_initial_state,
    fly_by_duration_s,
    fly_by_initial_state,
    hover_initial_state,
    in_plane_ellipse_initial_state,
    spiral_approach,
)

# The reference orbit of the tests: circular, 7000 km, ISS-like inclination.
A_M = 7000e3
N_RAD_S = math.sqrt(MU_EARTH_M3_S2 / A_M**3)
PERIOD_S = orbital_period_s(A_M)
INCLINATION_RAD = math.radians(51.6)
ARG_LATITUDE0_RAD = 0.5
TARGET = OrbitalElements(A_M, 0.0, INCLINATION_RAD, 0.3, 0.0, ARG_LATITUDE0_RAD)

# Round-off bounds for closed forms evaluated on km-scale offsets (eps * 1e3 m ~ 2e-13 m).
CLOSED_FORM_ATOL_M = 1e-9
CLOSED_FORM_ATOL_M_S = 1e-12

# A generic state with drift, radial, along-track and cross-track parts.
RHO0_M = np.array([120.0, -800.0, 300.0])
RHO_DOT0_M_S = np.array([0.3, -0.05, -0.2])


def cw_rhs(_t: float, state: np.ndarray) -> np.ndarray:
    x, _y, z, vx, vy, vz = state
    n = N_RAD_S
    return np.array([vx, vy, vz, 3.0 * n * n * x + 2.0 * n * vy, -2.0 * n * vx, -n * n * z])


def full_relative_motion(
    rho0_m: np.ndarray, rho_dot0_m_s: np.ndarray, times_s: np.ndarray, *, j2: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Relative RTN state from propagating both spacecraft with the full (nonlinear) gravity."""
    r_t0, v_t0 = state_from_elements(TARGET)
    r_c0, v_c0 = inertial_from_relative_rtn(r_t0, v_t0, rho0_m, rho_dot0_m_s)
    r_t, v_t = propagate(r_t0, v_t0, times_s, j2=j2, method="dop853")
    r_c, v_c = propagate(r_c0, v_c0, times_s, j2=j2, method="dop853")
    return relative_rtn(r_t, v_t, r_c, v_c)


def test_cw_solution_satisfies_the_hill_equations() -> None:
    h_s = 1.0
    t = np.linspace(0.0, 2.0 * PERIOD_S, 97)
    rho, rho_dot = cw_propagate(RHO0_M, RHO_DOT0_M_S, N_RAD_S, t)
    rho_plus, rho_dot_plus = cw_propagate(RHO0_M, RHO_DOT0_M_S, N_RAD_S, t + h_s)
    rho_minus, rho_dot_minus = cw_propagate(RHO0_M, RHO_DOT0_M_S, N_RAD_S, t - h_s)
    # The rate is the derivative of the position: central difference error h^2 n^3 |rho| / 6
    # ~ 3e-7 m/s.
    np.testing.assert_allclose(rho_dot, (rho_plus - rho_minus) / (2.0 * h_s), atol=1e-6)
    # Second derivative (error h^2 n^4 |rho| / 12 ~ 2e-10 m/s^2) against the right-hand side;
    # the accelerations themselves are ~ n^2 |rho| ~ 1e-3 m/s^2.
    accel = (rho_plus - 2.0 * rho + rho_minus) / h_s**2
    n = N_RAD_S
    x, z = rho[:, 0], rho[:, 2]
    vx, vy = rho_dot[:, 0], rho_dot[:, 1]
    rhs = np.stack([3.0 * n * n * x + 2.0 * n * vy, -2.0 * n * vx, -n * n * z], axis=-1)
    np.testing.assert_allclose(accel, rhs, atol=1e-9)
    # The analytic rate's own derivative gives the same right-hand side.
    np.testing.assert_allclose((rho_dot_plus - rho_dot_minus) / (2.0 * h_s), rhs, atol=1e-9)


def test_cw_solution_equals_a_numerical_integration_of_the_linear_equations() -> None:
    t = np.linspace(0.0, 2.0 * PERIOD_S, 41)
    rho, rho_dot = cw_propagate(RHO0_M, RHO_DOT0_M_S, N_RAD_S, t)
    solution = solve_ivp(
        cw_rhs,
        (0.0, t[-1]),
        np.concatenate([RHO0_M, RHO_DOT0_M_S]),
        method="DOP853",
        t_eval=t,
        rtol=1e-12,
        atol=1e-10,
    )
    assert solution.success
    np.testing.assert_allclose(rho, solution.y[:3].T, rtol=0.0, atol=1e-6)
    np.testing.assert_allclose(rho_dot, solution.y[3:].T, rtol=0.0, atol=1e-9)


def test_cw_solution_starts_at_the_initial_state_and_runs_backwards() -> None:
    rho, rho_dot = cw_propagate(RHO0_M, RHO_DOT0_M_S, N_RAD_S, [0.0])
    np.testing.assert_array_equal(rho[0], RHO0_M)
    np.testing.assert_array_equal(rho_dot[0], RHO_DOT0_M_S)
    t_s = 1234.5
    rho_t, rho_dot_t = cw_propagate(RHO0_M, RHO_DOT0_M_S, N_RAD_S, [t_s])
    rho_back, rho_dot_back = cw_propagate(rho_t[0], rho_dot_t[0], N_RAD_S, [-t_s])
    np.testing.assert_allclose(rho_back[0], RHO0_M, atol=CLOSED_FORM_ATOL_M)
    np.testing.assert_allclose(rho_dot_back[0], RHO_DOT0_M_S, atol=CLOSED_FORM_ATOL_M_S)


def test_fly_around_is_the_closed_form_circle_at_constant_range() -> None:
    radius_m, phase_rad = 1000.0, 0.7
    t = np.linspace(0.0, PERIOD_S, 181)
    for sign in (1, -1):
        rho0, rho_dot0 = fly_around_initial_state(radius_m, N_RAD_S, phase_rad, sign)
        rho, rho_dot = cw_propagate(rho0, rho_dot0, N_RAD_S, t)
        amplitude_m = radius_m / 2.0
        theta = N_RAD_S * t + phase_rad
        expected = amplitude_m * np.stack(
            [np.sin(theta), 2.0 * np.cos(theta), sign * math.sqrt(3.0) * np.sin(theta)], axis=-1
        )
        np.testing.assert_allclose(rho, expected, atol=CLOSED_FORM_ATOL_M)
        np.testing.assert_allclose(
            np.linalg.norm(rho, axis=1), radius_m, rtol=0.0, atol=CLOSED_FORM_ATOL_M
        )
        # A circle: the velocity stays perpendicular to the position at speed n radius.
        np.testing.assert_allclose(np.sum(rho * rho_dot, axis=1), 0.0, atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(rho_dot, axis=1), N_RAD_S * radius_m, rtol=1e-12)
        # In a fixed plane through T tilted 60 deg from the orbit plane (normal 60 deg from N).
        normal = np.cross(rho, rho_dot)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        np.testing.assert_allclose(normal, np.broadcast_to(normal[0], normal.shape), atol=1e-12)
        assert abs(normal[0, 1]) < 1e-12
        assert math.degrees(math.acos(abs(normal[0, 2]))) == pytest.approx(60.0, abs=1e-9)
        # The motion turns about (sign sqrt(3), 0, -1) / 2: the tilt follows cross_track_sign.
        np.testing.assert_allclose(normal[0], [sign * math.sqrt(3.0) / 2.0, 0.0, -0.5], atol=1e-12)
        # Period: one revolution of the target. The position angle grows as n t and the state
        # closes after exactly 2 pi / n, not after half of it.
        np.testing.assert_allclose(rho[-1], rho0, atol=CLOSED_FORM_ATOL_M)
        np.testing.assert_allclose(rho_dot[-1], rho_dot0, atol=CLOSED_FORM_ATOL_M_S)
        assert np.linalg.norm(rho[90] - rho0) > radius_m


def test_in_plane_ellipse_is_the_two_to_one_ellipse() -> None:
    b_m, phase_rad = 250.0, -1.1
    rho0, rho_dot0 = in_plane_ellipse_initial_state(b_m, N_RAD_S, phase_rad)
    t = np.linspace(0.0, PERIOD_S, 73)
    rho, _ = cw_propagate(rho0, rho_dot0, N_RAD_S, t)
    theta = N_RAD_S * t + phase_rad
    np.testing.assert_allclose(rho[:, 0], b_m * np.sin(theta), atol=CLOSED_FORM_ATOL_M)
    np.testing.assert_allclose(rho[:, 1], 2.0 * b_m * np.cos(theta), atol=CLOSED_FORM_ATOL_M)
    np.testing.assert_array_equal(rho[:, 2], 0.0)
    np.testing.assert_allclose(
        (rho[:, 0] / b_m) ** 2 + (rho[:, 1] / (2.0 * b_m)) ** 2, 1.0, rtol=1e-12
    )


def test_cw_fly_around_against_full_two_body_and_j2_propagation() -> None:
    # A 1 km fly-around of a target on a 7000 km circular orbit, over one orbit.
    radius_m = 1000.0
    t = np.linspace(0.0, PERIOD_S, 121)
    rho0, rho_dot0 = fly_around_initial_state(radius_m, N_RAD_S)
    rho_cw, _ = cw_propagate(rho0, rho_dot0, N_RAD_S, t)

    # Two-body: the second-order energy excess (semi-major axis 2 rho^2 / a too large, module
    # docstring) makes the observer fall behind by 6 pi rho^2 / a per orbit (2.69 m); the
    # periodic second-order terms are of size 3 rho^2 / (2 a) = 0.21 m and vanish again after
    # a whole orbit.
    rho_2b, _ = full_relative_motion(rho0, rho_dot0, t, j2=False)
    difference_2b_m = np.linalg.norm(rho_2b - rho_cw, axis=1)
    secular_m = 6.0 * math.pi * radius_m**2 / A_M
    periodic_m = 3.0 * radius_m**2 / (2.0 * A_M)
    assert difference_2b_m.max() <= secular_m + periodic_m
    assert rho_2b[-1, 1] - rho_cw[-1, 1] == pytest.approx(-secular_m, abs=0.5 * periodic_m)

    # J2: the osculating-to-mean semi-major axis differs between the two objects by up to
    # 3 J2 (R / a)^2 rho (module docstring), drifting 3 pi times that per orbit (25 m at most
    # for 1 km); the radial and cross-track offsets of the fly-around add terms of the same
    # order, hence the factor 2 of margin.
    rho_j2, _ = full_relative_motion(rho0, rho_dot0, t, j2=True)
    difference_j2_m = np.linalg.norm(rho_j2 - rho_cw, axis=1)
    j2_drift_m = 3.0 * math.pi * 3.0 * J2 * (EARTH_EQUATORIAL_RADIUS_M / A_M) ** 2 * radius_m
    assert difference_j2_m.max() <= 2.0 * j2_drift_m + secular_m
    print(
        f"CW vs full over one orbit, 1 km fly-around at 7000 km: two-body max "
        f"{difference_2b_m.max():.3f} m, two-body + J2 max {difference_j2_m.max():.3f} m"
    )


def test_fly_by_passes_at_the_miss_distance_at_the_predicted_time() -> None:
    for miss_m, start_m in ((200.0, 3000.0), (-150.0, -2000.0)):
        rho0, rho_dot0 = fly_by_initial_state(miss_m, start_m, N_RAD_S)
        duration_s = fly_by_duration_s(miss_m, start_m, N_RAD_S)
        assert duration_s == pytest.approx(4.0 * start_m / (3.0 * N_RAD_S * miss_m), rel=1e-15)
        t = np.linspace(0.0, duration_s, 2001)
        rho, rho_dot = cw_propagate(rho0, rho_dot0, N_RAD_S, t)
        # The radial offset holds and the along-track position drifts uniformly.
        np.testing.assert_allclose(rho[:, 0], miss_m, atol=CLOSED_FORM_ATOL_M)
        np.testing.assert_allclose(rho[:, 2], 0.0, atol=0.0)
        np.testing.assert_allclose(rho_dot[:, 1], -1.5 * N_RAD_S * miss_m, rtol=1e-12)
        # Closest approach at half the duration, at the miss distance; symmetric end.
        rng = np.linalg.norm(rho, axis=1)
        assert int(np.argmin(rng)) == 1000
        closest, _ = cw_propagate(rho0, rho_dot0, N_RAD_S, [0.5 * duration_s])
        assert np.linalg.norm(closest[0]) == pytest.approx(abs(miss_m), abs=CLOSED_FORM_ATOL_M)
        np.testing.assert_allclose(rho[-1], [miss_m, -start_m, 0.0], atol=CLOSED_FORM_ATOL_M)


def test_fly_by_that_would_never_pass_is_rejected() -> None:
    with pytest.raises(SatsightError, match=r"never pass the target.*towards -T"):
        fly_by_initial_state(200.0, -3000.0, N_RAD_S)
    with pytest.raises(SatsightError, match=r"never pass the target.*towards \+T"):
        fly_by_duration_s(-200.0, 3000.0, N_RAD_S)
    with pytest.raises(SatsightError, match="no drift"):
        fly_by_initial_state(0.0, 3000.0, N_RAD_S)


def test_hover_is_an_equilibrium_of_cw_and_of_the_full_dynamics() -> None:
    range_m = 1000.0
    t = np.linspace(0.0, PERIOD_S, 61)
    rho0, rho_dot0 = hover_initial_state(range_m)
    np.testing.assert_array_equal(rho0, [0.0, -range_m, 0.0])
    np.testing.assert_array_equal(rho_dot0, 0.0)
    rho, rho_dot = cw_propagate(rho0, rho_dot0, N_RAD_S, t)
    np.testing.assert_allclose(rho, np.broadcast_to(rho0, rho.shape), atol=1e-12)
    np.testing.assert_allclose(rho_dot, 0.0, atol=1e-15)

    # The linear hover point is range^2 / (2 a) above the orbit; under two-body gravity it
    # falls behind by 6 pi range^2 / a per orbit (docstring).
    rho_2b, _ = full_relative_motion(rho0, rho_dot0, t, j2=False)
    assert rho_2b[-1, 1] - rho0[1] == pytest.approx(-6.0 * math.pi * range_m**2 / A_M, rel=1e-3)

    # Built as the same circular orbit shifted in phase it stays put under two-body gravity.
    for sign in (-1, 1):
        rho0, rho_dot0 = hover_initial_state(range_m, sign, orbit_radius_m=A_M)
        assert np.linalg.norm(rho0) == pytest.approx(range_m, rel=1e-15)
        assert rho0[0] == pytest.approx(-(range_m**2) / (2.0 * A_M), rel=1e-6)
        rho_2b, rho_dot_2b = full_relative_motion(rho0, rho_dot0, t, j2=False)
        drift_2b_m = np.linalg.norm(rho_2b - rho0, axis=1).max()
        assert drift_2b_m < 1e-3
        np.testing.assert_allclose(rho_dot_2b, 0.0, atol=1e-6)

        # With J2 the two objects, at the same osculating state half a milliradian apart in
        # argument of latitude u, differ in mean semi-major axis by
        # -sign 3 J2 (R / a)^2 sin^2(i) sin(2 u) range (short-period term
        # (3/2) J2 R^2 / a sin^2(i) cos(2 u) of a), and drift 3 pi times that per orbit.
        rho_j2, _ = full_relative_motion(rho0, rho_dot0, t, j2=True)
        predicted_m = (
            -sign
            * 9.0
            * math.pi
            * J2
            * (EARTH_EQUATORIAL_RADIUS_M / A_M) ** 2
            * math.sin(INCLINATION_RAD) ** 2
            * math.sin(2.0 * ARG_LATITUDE0_RAD)
            * range_m
        )
        assert rho_j2[-1, 1] - rho0[1] == pytest.approx(predicted_m, rel=0.05)
        drift_j2_m = np.linalg.norm(rho_j2 - rho0, axis=1).max()
        print(
            f"hover 1 km ({'ahead' if sign > 0 else 'behind'}), one orbit: two-body drift "
            f"{drift_2b_m:.2e} m, J2 drift max {drift_j2_m:.2f} m "
            f"(along-track {rho_j2[-1, 1] - rho0[1]:+.2f} m, predicted {predicted_m:+.2f} m)"
        )


def test_hover_rejects_bad_input() -> None:
    with pytest.raises(SatsightError, match="along_track_sign"):
        hover_initial_state(100.0, 0)
    with pytest.raises(SatsightError, match="diameter"):
        hover_initial_state(3.0, orbit_radius_m=1.0)
    with pytest.raises(SatsightError, match="range_m"):
        hover_initial_state(-1.0)


def test_spiral_passes_the_end_ranges_and_decays_geometrically() -> None:
    start_m, end_m = 50e3, 500.0
    t = np.linspace(100.0, 100.0 + 3.0 * PERIOD_S, 3001)
    rho, rho_dot = spiral_approach(t, start_m, end_m, N_RAD_S)
    rng = np.linalg.norm(rho, axis=1)
    assert rng[0] == pytest.approx(start_m, rel=1e-15)
    assert rng[-1] == pytest.approx(end_m, rel=1e-15)
    assert np.all(np.diff(rng) < 0.0)
    # Equal times, equal ratios: the interval boundaries 50 -> 40 -> ... -> 0.5 km are
    # reached at the fractions ln(r0 / r) / ln(r0 / r1) of the span.
    boundaries_m = np.array([50e3, 40e3, 30e3, 20e3, 10e3, 5e3, 500.0])
    fractions = np.log(start_m / boundaries_m) / math.log(start_m / end_m)
    t_boundaries = t[0] + fractions * (t[-1] - t[0])
    rho_b, _ = spiral_approach(np.append(t_boundaries, t[-1]), start_m, end_m, N_RAD_S)
    np.testing.assert_allclose(np.linalg.norm(rho_b[:-1], axis=1), boundaries_m, rtol=1e-12)
    # The analytic rate against central differences (step 1 s: error h^2 |d3 rho / dt3| / 6,
    # dominated by the turn, ~ n^3 r / 6 ~ 1.2e-5 m/s at 50 km). The span is fixed by the first
    # and last samples, so the shifted samples go on one ascending grid between them.
    h_s = 1.0
    inner = t[1:-1]
    grid = np.concatenate([[t[0]], np.stack([inner - h_s, inner, inner + h_s], 1).ravel(), [t[-1]]])
    rho_grid, rho_dot_grid = spiral_approach(grid, start_m, end_m, N_RAD_S)
    minus, centre, plus = (rho_grid[1:-1].reshape(-1, 3, 3)[:, k] for k in range(3))
    np.testing.assert_allclose(centre, rho[1:-1], rtol=1e-13)
    np.testing.assert_allclose(rho_dot_grid[2:-1:3], rho_dot[1:-1], rtol=1e-13)
    finite = (plus - minus) / (2.0 * h_s)
    np.testing.assert_allclose(finite, rho_dot[1:-1], rtol=0.0, atol=2e-5)


def test_spiral_via_interval_edges_spends_equal_time_in_each_interval() -> None:
    edges_m = np.array([50e3, 40e3, 30e3, 20e3, 10e3, 5e3, 500.0])
    span_s = 3.0 * PERIOD_S
    via = tuple(edges_m[1:-1])
    # The edges at k / 6 of the span, exactly.
    t_edges = np.linspace(0.0, span_s, 7)
    rho, _ = spiral_approach(t_edges, 50e3, 500.0, N_RAD_S, via_ranges_m=via)
    np.testing.assert_allclose(np.linalg.norm(rho, axis=1), edges_m, rtol=1e-12)
    # Inside a segment the decay is geometric: the midpoint range is the geometric mean.
    t_mid = np.array([0.0, 3.5 / 6.0 * span_s, span_s])  # the middle of 20 -> 10 km
    rho_mid, rho_dot_mid = spiral_approach(t_mid, 50e3, 500.0, N_RAD_S, via_ranges_m=via)
    assert np.linalg.norm(rho_mid[1]) == pytest.approx(math.sqrt(20e3 * 10e3), rel=1e-12)
    # The analytic rate against a central difference inside that segment.
    h_s = 0.5
    grid = np.array([0.0, t_mid[1] - h_s, t_mid[1] + h_s, span_s])
    rho_h, _ = spiral_approach(grid, 50e3, 500.0, N_RAD_S, via_ranges_m=via)
    finite = (rho_h[2] - rho_h[1]) / (2.0 * h_s)
    np.testing.assert_allclose(finite, rho_dot_mid[1], rtol=0.0, atol=1e-5)
    for bad in ((60e3,), (30e3, 40e3), (0.0,)):
        with pytest.raises(SatsightError, match="via_ranges_m"):
            spiral_approach(t_edges, 50e3, 500.0, N_RAD_S, via_ranges_m=bad)


def test_spiral_at_constant_range_is_the_natural_fly_around() -> None:
    t = np.linspace(0.0, 1.5 * PERIOD_S, 91)
    for sign in (1, -1):
        rho, rho_dot = spiral_approach(
            t, 800.0, 800.0, N_RAD_S, phase_rad=0.4, cross_track_sign=sign
        )
        rho0, rho_dot0 = fly_around_initial_state(800.0, N_RAD_S, 0.4, sign)
        rho_cw, rho_dot_cw = cw_propagate(rho0, rho_dot0, N_RAD_S, t)
        np.testing.assert_allclose(rho, rho_cw, atol=CLOSED_FORM_ATOL_M)
        np.testing.assert_allclose(rho_dot, rho_dot_cw, atol=CLOSED_FORM_ATOL_M_S)


def test_spiral_revolutions_set_the_turn_rate() -> None:
    t = np.linspace(0.0, 2000.0, 401)
    rho, _ = spiral_approach(t, 10e3, 1e3, N_RAD_S, revolutions=3.0)
    u = rho / np.linalg.norm(rho, axis=1, keepdims=True)
    np.testing.assert_allclose(u[-1], u[0], atol=1e-12)  # three whole turns
    # Half-way (1.5 turns) the direction is reversed.
    np.testing.assert_allclose(u[200], -u[0], atol=1e-12)
    with pytest.raises(SatsightError, match="ascending"):
        spiral_approach(t[::-1], 10e3, 1e3, N_RAD_S)
    with pytest.raises(SatsightError, match="end_range_m"):
        spiral_approach(t, 10e3, 0.0, N_RAD_S)
