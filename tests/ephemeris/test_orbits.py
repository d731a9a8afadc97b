"""Orbital elements, state vectors and two-body + J2 propagation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.orbits import (
    J2,
    MU_EARTH_M3_S2,
    OrbitalElements,
    elements_from_state,
    gravity_acceleration_m_s2,
    orbital_period_s,
    propagate,
    state_from_elements,
)
from satsight.errors import SatsightError

PROPERTY = settings(max_examples=200, deadline=None)
KM = 1e3

# Vallado, "Fundamentals of Astrodynamics and Applications", 4th ed., Examples 2-5 and 2-6.
VALLADO_R_M = np.array([6524.834, 6862.875, 6448.296]) * KM
VALLADO_V_M_S = np.array([4.901327, 5.533756, -1.976341]) * KM


def leo_elements(e: float = 0.001, i_deg: float = 51.6) -> OrbitalElements:
    return OrbitalElements.from_km_deg(7000.0, e, i_deg, 30.0, 40.0, 0.0)


def specific_energy(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    return 0.5 * np.sum(v * v, axis=-1) - MU_EARTH_M3_S2 / np.linalg.norm(r, axis=-1)


def angular_momentum(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.cross(r, v), axis=-1)


# --- elements <-> state: textbook examples -----------------------------------------------


def test_vallado_example_2_5_state_to_elements() -> None:
    # Printed: p = 11067.790 km, a = 36127.343 km, e = 0.832853, i = 87.870 deg,
    # RAAN = 227.898 deg, argp = 53.38 deg, nu = 92.335 deg. Vallado's hand computation
    # carries rounded intermediates: in float64 p and a differ from the print by 8 and 5 m
    # and i by 0.0009 deg (i = atan2(|h_xy|, h_z) does not even depend on mu), so p and a
    # are checked to 0.01 km and i to 0.001 deg; the other elements to the printed digits.
    el = elements_from_state(VALLADO_R_M, VALLADO_V_M_S)
    assert el.semi_latus_rectum_m / KM == pytest.approx(11067.790, abs=0.01)
    assert el.semi_major_axis_m / KM == pytest.approx(36127.343, abs=0.01)
    assert el.eccentricity == pytest.approx(0.832853, abs=5e-7)
    assert math.degrees(el.inclination_rad) == pytest.approx(87.870, abs=1e-3)
    assert math.degrees(el.raan_rad) == pytest.approx(227.898, abs=5e-4)
    assert math.degrees(el.arg_perigee_rad) == pytest.approx(53.38, abs=5e-3)
    assert math.degrees(el.true_anomaly_rad) == pytest.approx(92.335, abs=5e-4)


def test_vallado_example_2_6_elements_to_state() -> None:
    # Vallado's inputs (p = 11067.790 km, e = 0.83285, i = 87.87, RAAN = 227.89,
    # argp = 53.38, nu = 92.335 deg) give, printed, r = [6525.368, 6861.532, 6449.119] km
    # and v = [4.902279, 5.533140, -1.975710] km/s: checked to half the last printed digit.
    p_km, e = 11067.790, 0.83285
    el = OrbitalElements.from_km_deg(p_km / (1.0 - e * e), e, 87.87, 227.89, 53.38, 92.335)
    r, v = state_from_elements(el)
    np.testing.assert_allclose(r / KM, [6525.368, 6861.532, 6449.119], rtol=0, atol=5e-4)
    np.testing.assert_allclose(v / KM, [4.902279, 5.533140, -1.975710], rtol=0, atol=5e-7)


def test_curtis_example_4_3_state_to_elements() -> None:
    # Curtis, "Orbital Mechanics for Engineering Students", Example 4.3 (mu = 398600 km^3/s^2):
    # r = [-6045, -3490, 2500] km, v = [-3.457, 6.618, 2.533] km/s -> h = 58310 km^2/s,
    # i = 153.2, RAAN = 255.3, e = 0.1712, argp = 20.07, theta = 28.45 deg, a = 8788 km.
    mu = 398600.0e9
    r = np.array([-6045.0, -3490.0, 2500.0]) * KM
    v = np.array([-3.457, 6.618, 2.533]) * KM
    el = elements_from_state(r, v, mu)
    assert angular_momentum(r, v) / 1e6 == pytest.approx(58310.0, abs=5.0)
    assert math.degrees(el.inclination_rad) == pytest.approx(153.2, abs=0.05)
    assert math.degrees(el.raan_rad) == pytest.approx(255.3, abs=0.05)
    assert el.eccentricity == pytest.approx(0.1712, abs=5e-5)
    assert math.degrees(el.arg_perigee_rad) == pytest.approx(20.07, abs=5e-3)
    assert math.degrees(el.true_anomaly_rad) == pytest.approx(28.45, abs=5e-3)
    assert el.semi_major_axis_m / KM == pytest.approx(8788.0, abs=0.5)


# --- elements <-> state: properties and singular cases -----------------------------------

_elements = st.builds(
    OrbitalElements.from_km_deg,
    st.floats(6600.0, 45000.0),
    st.floats(0.0, 0.8),
    st.floats(0.01, 179.99),
    st.floats(0.0, 360.0),
    st.floats(0.0, 360.0),
    st.floats(0.0, 360.0),
)


def assert_same_state(r1, v1, r2, v2, rtol: float = 1e-8) -> None:
    assert np.linalg.norm(r1 - r2) <= rtol * np.linalg.norm(r1)
    assert np.linalg.norm(v1 - v2) <= rtol * np.linalg.norm(v1)


@PROPERTY
@given(_elements)
def test_state_elements_state_round_trip(el: OrbitalElements) -> None:
    r, v = state_from_elements(el)
    el2 = elements_from_state(r, v)
    r2, v2 = state_from_elements(el2)
    assert_same_state(r, v, r2, v2)
    assert el2.semi_major_axis_m == pytest.approx(el.semi_major_axis_m, rel=1e-9)
    assert el2.eccentricity == pytest.approx(el.eccentricity, abs=1e-9)
    assert el2.inclination_rad == pytest.approx(el.inclination_rad, abs=1e-9)


@PROPERTY
@given(_elements)
def test_regular_elements_are_recovered(el: OrbitalElements) -> None:
    # Away from the singular cases every angle comes back (modulo 2 pi).
    if el.eccentricity < 1e-3:
        return
    el2 = elements_from_state(*state_from_elements(el))
    for name in ("raan_rad", "arg_perigee_rad", "true_anomaly_rad"):
        difference = (getattr(el2, name) - getattr(el, name) + math.pi) % (2 * math.pi) - math.pi
        assert abs(difference) < 1e-7, name


def test_circular_orbit_convention() -> None:
    # e = 0: argp = 0 and nu is the argument of latitude (argp + nu of the input).
    el = OrbitalElements.from_km_deg(7000.0, 0.0, 40.0, 10.0, 70.0, 20.0)
    r, v = state_from_elements(el)
    el2 = elements_from_state(r, v)
    assert el2.arg_perigee_rad == 0.0
    assert el2.eccentricity < 1e-11
    assert el2.raan_rad == pytest.approx(math.radians(10.0), abs=1e-12)
    assert el2.true_anomaly_rad == pytest.approx(math.radians(90.0), abs=1e-12)
    assert_same_state(r, v, *state_from_elements(el2), rtol=1e-12)


@pytest.mark.parametrize("i_deg", [0.0, 180.0])
def test_equatorial_orbit_convention(i_deg: float) -> None:
    # i = 0 or 180: raan = 0 and argp is the longitude of perigee, in the direction of motion.
    el = OrbitalElements.from_km_deg(8000.0, 0.1, i_deg, 0.0, 30.0, 50.0)
    r, v = state_from_elements(el)
    el2 = elements_from_state(r, v)
    assert el2.raan_rad == 0.0
    assert el2.inclination_rad == pytest.approx(math.radians(i_deg), abs=1e-12)
    assert el2.arg_perigee_rad == pytest.approx(math.radians(30.0), abs=1e-9)
    assert el2.true_anomaly_rad == pytest.approx(math.radians(50.0), abs=1e-9)
    assert_same_state(r, v, *state_from_elements(el2), rtol=1e-12)


def test_circular_equatorial_orbit_convention() -> None:
    # raan = argp = 0 and nu is the true longitude, from the x axis.
    r = np.array([0.0, 7000.0, 0.0]) * KM
    v = np.array([-math.sqrt(MU_EARTH_M3_S2 / 7000e3), 0.0, 0.0])
    el = elements_from_state(r, v)
    assert (el.raan_rad, el.arg_perigee_rad) == (0.0, 0.0)
    assert el.true_anomaly_rad == pytest.approx(math.pi / 2, abs=1e-12)
    assert_same_state(r, v, *state_from_elements(el), rtol=1e-12)


def test_from_km_deg_converts_units() -> None:
    el = OrbitalElements.from_km_deg(7000.0, 0.01, 90.0, 180.0, 45.0, 360.0)
    assert el.semi_major_axis_m == 7e6
    assert el.inclination_rad == pytest.approx(math.pi / 2)
    assert el.raan_rad == pytest.approx(math.pi)
    assert el.arg_perigee_rad == pytest.approx(math.pi / 4)
    assert el.true_anomaly_rad == pytest.approx(2 * math.pi)


@pytest.mark.parametrize(
    ("a_km", "e", "i_deg", "match"),
    [
        (-7000.0, 0.0, 10.0, "semi_major_axis_m must be > 0"),
        (7000.0, 1.0, 10.0, "0 <= e < 1"),
        (7000.0, -0.1, 10.0, "0 <= e < 1"),
        (7000.0, 0.1, 181.0, r"\[0, pi\]"),
        (float("nan"), 0.1, 10.0, "finite"),
    ],
)
def test_invalid_elements_are_rejected(a_km: float, e: float, i_deg: float, match: str) -> None:
    with pytest.raises(SatsightError, match=match):
        OrbitalElements.from_km_deg(a_km, e, i_deg, 0.0, 0.0, 0.0)


def test_open_and_degenerate_states_are_rejected() -> None:
    r = np.array([7000e3, 0.0, 0.0])
    escape = math.sqrt(2 * MU_EARTH_M3_S2 / 7000e3)
    with pytest.raises(SatsightError, match="elliptical"):
        elements_from_state(r, np.array([0.0, 1.01 * escape, 0.0]))
    with pytest.raises(SatsightError, match="parallel"):
        elements_from_state(r, np.array([1000.0, 0.0, 0.0]))
    with pytest.raises(SatsightError, match="shape"):
        elements_from_state(r[:2], np.zeros(3))


# --- gravity ------------------------------------------------------------------------------


def j2_potential(r: np.ndarray) -> float:
    """J2 part of the potential, J2 mu R^2 / (2 r^3) (3 z^2 / r^2 - 1), J/kg (a = -grad U)."""
    rn = float(np.linalg.norm(r))
    return (
        -J2
        * MU_EARTH_M3_S2
        * EARTH_EQUATORIAL_RADIUS_M**2
        / (2 * rn**3)
        * (1.0 - 3.0 * r[2] ** 2 / rn**2)
    )


def test_j2_acceleration_is_the_gradient_of_the_j2_potential() -> None:
    # Potential per unit mass V = -mu/r [1 - J2 (R/r)^2 P2(sin(lat))], a = -grad V.
    points = np.array([[7000e3, 0.0, 0.0], [4000e3, -3000e3, 5000e3], [100e3, 200e3, -8000e3]])
    for r in points:
        j2_part = gravity_acceleration_m_s2(r) - gravity_acceleration_m_s2(r, j2=False)
        step = 1.0
        gradient = np.array(
            [
                (j2_potential(r + step * e) - j2_potential(r - step * e)) / (2 * step)
                for e in np.eye(3)
            ]
        )
        np.testing.assert_allclose(j2_part, -gradient, rtol=1e-6)
        np.testing.assert_allclose(
            gravity_acceleration_m_s2(r, j2=False),
            -MU_EARTH_M3_S2 * r / np.linalg.norm(r) ** 3,
            rtol=1e-15,
        )
    # Vectorised over (N, 3).
    np.testing.assert_allclose(
        gravity_acceleration_m_s2(points),
        np.array([gravity_acceleration_m_s2(p) for p in points]),
        rtol=1e-15,
    )


# --- propagation --------------------------------------------------------------------------


def test_two_body_dop853_conserves_energy_and_angular_momentum_over_a_day() -> None:
    # Measured drifts: 3e-12 (energy) and 2e-12 (angular momentum) relative over one day.
    r0, v0 = state_from_elements(OrbitalElements.from_km_deg(7000.0, 0.05, 60.0, 20, 30, 0))
    times = np.linspace(0.0, 86400.0, 97)
    r, v = propagate(r0, v0, times, j2=False, method="dop853")
    energy, h = specific_energy(r, v), angular_momentum(r, v)
    assert np.max(np.abs(energy / energy[0] - 1.0)) < 1e-9
    assert np.max(np.abs(h / h[0] - 1.0)) < 1e-9
    np.testing.assert_array_equal(r[0], r0)


def test_two_body_rk4_conserves_energy_over_a_few_orbits() -> None:
    # RK4's energy error grows like (omega h)^4 per radian of orbit: with omega h ~ 1e-3 at
    # 1 s in LEO that is ~1e-12 per orbit as an upper estimate; measured, the drift over 3
    # orbits is ~2e-14 relative (round-off level). Asserted below 1e-12, a 50x margin.
    r0, v0 = state_from_elements(leo_elements())
    period = orbital_period_s(7000e3)
    times = np.linspace(0.0, 3 * period, 31)
    r, v = propagate(r0, v0, times, j2=False, method="rk4", step_s=1.0)
    energy, h = specific_energy(r, v), angular_momentum(r, v)
    assert np.max(np.abs(energy / energy[0] - 1.0)) < 1e-12
    assert np.max(np.abs(h / h[0] - 1.0)) < 1e-12


def test_rk4_at_1_s_agrees_with_dop853_after_one_orbit_with_j2() -> None:
    # Measured: 2e-5 m and 2e-8 m/s apart after one 7000 km orbit.
    r0, v0 = state_from_elements(leo_elements())
    times = np.array([0.0, orbital_period_s(7000e3)])
    r_rk4, v_rk4 = propagate(r0, v0, times, method="rk4", step_s=1.0)
    r_dop, v_dop = propagate(r0, v0, times, method="dop853")
    assert np.linalg.norm(r_rk4[-1] - r_dop[-1]) < 1.0
    assert np.linalg.norm(v_rk4[-1] - v_dop[-1]) < 1e-3
    # J2 really acts: it moves the object by kilometres in one orbit.
    r_kepler, _ = propagate(r0, v0, times, j2=False, method="dop853")
    assert np.linalg.norm(r_kepler[-1] - r_dop[-1]) > 1e3


def test_rk4_lands_exactly_on_requested_times() -> None:
    # Off-grid times (shortened last step) match one long run through the same instants.
    r0, v0 = state_from_elements(leo_elements())
    times = np.array([0.0, 0.3, 2.7, 2.7, 10.0, 17.25])
    r, v = propagate(r0, v0, times, step_s=1.0)
    r_dop, v_dop = propagate(r0, v0, times, method="dop853")
    np.testing.assert_allclose(r, r_dop, rtol=0, atol=1e-5)
    np.testing.assert_allclose(v, v_dop, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(r[2], r[3])
    assert r.shape == v.shape == (6, 3)


def test_j2_nodal_regression_matches_the_secular_rate() -> None:
    # dRAAN/dt = -3/2 n J2 (R/p)^2 cos i (Vallado, 4th ed., Ch. 9; Curtis, 3rd ed.,
    # Sec. 4.7). Osculating RAAN oscillates (here ~8e-4 rad peak to peak, twice per orbit)
    # about the secular drift, so the rate is a linear fit over 15 orbits (~24 h) sampled
    # uniformly in time. Measured agreement 0.13 %; the residual is the difference between
    # osculating and mean elements in n and p (order J2).
    el = leo_elements()
    r0, v0 = state_from_elements(el)
    period = orbital_period_s(el.semi_major_axis_m)
    times = np.linspace(0.0, 15 * period, 15 * 100 + 1)
    r, v = propagate(r0, v0, times, method="dop853")
    raan = np.unwrap([elements_from_state(ri, vi).raan_rad for ri, vi in zip(r, v, strict=True)])
    rate_fit = np.polyfit(times, raan, 1)[0]
    n = math.sqrt(MU_EARTH_M3_S2 / el.semi_major_axis_m**3)
    rate_secular = (
        -1.5
        * n
        * J2
        * (EARTH_EQUATORIAL_RADIUS_M / el.semi_latus_rectum_m) ** 2
        * math.cos(el.inclination_rad)
    )
    assert math.degrees(rate_secular) * 86400 == pytest.approx(-4.47, abs=0.01)  # deg/day
    assert rate_fit == pytest.approx(rate_secular, rel=0.01)


def test_circular_two_body_orbit_returns_after_one_period() -> None:
    a = 7000e3
    r0, v0 = state_from_elements(OrbitalElements(a, 0.0, 0.7, 0.2, 0.0, 0.4))
    period = orbital_period_s(a)
    assert period == pytest.approx(2 * math.pi * math.sqrt(a**3 / MU_EARTH_M3_S2), rel=1e-15)
    for method in ("dop853", "rk4"):
        r, v = propagate(r0, v0, [0.5 * period, period], j2=False, method=method)
        assert np.linalg.norm(r[-1] - r0) < 1e-6 * a
        assert np.linalg.norm(v[-1] - v0) < 1e-6 * np.linalg.norm(v0)
        np.testing.assert_allclose(r[0], -r0, atol=1e-6 * a)  # half way round


def test_zero_time_returns_the_initial_state() -> None:
    r0, v0 = state_from_elements(leo_elements())
    for method in ("rk4", "dop853"):
        r, v = propagate(r0, v0, [0.0, 0.0], method=method)
        np.testing.assert_array_equal(r, [r0, r0])
        np.testing.assert_array_equal(v, [v0, v0])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"times_s": [10.0, 5.0]}, "ascending"),
        ({"times_s": [-1.0, 5.0]}, ">= 0"),
        ({"times_s": [0.0, float("inf")]}, "finite"),
        ({"times_s": []}, "non-empty"),
        ({"step_s": 0.0}, "step_s"),
        ({"step_s": -1.0}, "step_s"),
        ({"method": "euler"}, "method"),
        ({"r0_m": [7e6, float("nan"), 0.0]}, "r0_m must be finite"),
        ({"v0_m_s": [0.0, 7500.0]}, "shape"),
        ({"mu_m3_s2": 0.0}, "mu_m3_s2"),
    ],
)
def test_bad_propagation_input_is_rejected(kwargs: dict, match: str) -> None:
    arguments = {"r0_m": [7e6, 0.0, 0.0], "v0_m_s": [0.0, 7500.0, 0.0], "times_s": [0.0, 1.0]}
    arguments.update(kwargs)
    r0, v0, times = arguments.pop("r0_m"), arguments.pop("v0_m_s"), arguments.pop("times_s")
    with pytest.raises(SatsightError, match=match):
        propagate(r0, v0, times, **arguments)
