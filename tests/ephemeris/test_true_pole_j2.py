"""Zonal gravity about the Earth's true pole, against an independent integration.

Oracles: ERFA (through pyerfa, shipped with astropy) for the pole, ``pnm06a`` (IAU 2006
precession + IAU 2000A nutation, a separate implementation from skyfield's), a separate
scipy DOP853 integration that rotates the state into the true-equator frame at every call
and applies the textbook component form of J2 there, and finite differences of the zonal
potential for the acceleration. No network: ``pnm06a`` needs no IERS tables.
"""

from __future__ import annotations

import math

import erfa
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris import earth_orientation as eo
from satsight.ephemeris.orbits import (
    J2,
    J3,
    J4,
    MU_EARTH_M3_S2,
    OrbitalElements,
    gravity_acceleration_m_s2,
    orbital_period_s,
    propagate,
    state_from_elements,
)
from satsight.ephemeris.time import parse_epoch_utc
from satsight.errors import SatsightError
from tolerances import MAS_RAD

ONE_M = 1.0
ONE_CM = 0.01

EPOCH_2025 = "2025-06-21T06:00:00Z"
EPOCH_2050 = "2050-06-21T06:00:00Z"


def leo() -> OrbitalElements:
    """A 7000 km inclined LEO (51.6 deg) with a small eccentricity."""
    return OrbitalElements.from_km_deg(7000.0, 0.001, 51.6, 120.0, 40.0, 10.0)


def sun_synchronous() -> OrbitalElements:
    """A 7000 km near-polar orbit (97.9 deg, RAAN 0) placed where the tilt matters most.

    The error of J2 about GCRS z after one orbit depends on the orbit's orientation and
    phase against the pole's offset: from 2 m to 650 m at 2025 over RAAN and argument of
    latitude; this orbit sits near the top of that range, as the issue's did.
    """
    return OrbitalElements.from_km_deg(7000.0, 0.001, 97.9, 0.0, 40.0, 0.0)


def erfa_pole(epoch: str, t_s: np.ndarray) -> np.ndarray:
    """(N, 3) CIP in GCRS from ERFA: the third row of the bias-precession-nutation matrix."""
    t0 = parse_epoch_utc(epoch)
    fraction = float(t0.tt_fraction) + np.asarray(t_s, dtype=np.float64) / 86_400.0
    return erfa.pnm06a(float(t0.whole), fraction)[..., 2, :]


def oracle_true_pole_j2(epoch: str, r0: np.ndarray, v0: np.ndarray, t_end_s: float):
    """Two-body + J2 integrated in GCRS with J2 evaluated in the true-equator frame of date.

    At each call the position is rotated by ERFA's NPB matrix into the frame whose z axis
    is the CIP, J2 is applied there in the textbook component form (Vallado, 4th ed.,
    Ch. 8; Curtis, 3rd ed., Ch. 10), and the result is rotated back.
    """
    t0 = parse_epoch_utc(epoch)
    whole, fraction = float(t0.whole), float(t0.tt_fraction)
    k_j2 = -1.5 * J2 * MU_EARTH_M3_S2 * EARTH_EQUATORIAL_RADIUS_M**2

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        R_tod_from_gcrs = erfa.pnm06a(whole, fraction + t / 86_400.0)
        x, yy, z = R_tod_from_gcrs @ y[:3]
        r_sq = x * x + yy * yy + z * z
        r = math.sqrt(r_sq)
        s = 5.0 * z * z / r_sq
        f = k_j2 / r**5
        a_j2_tod = np.array([f * x * (1.0 - s), f * yy * (1.0 - s), f * z * (3.0 - s)])
        a = -MU_EARTH_M3_S2 * y[:3] / r**3 + R_tod_from_gcrs.T @ a_j2_tod
        return np.concatenate([y[3:], a])

    atol = np.array([1e-7] * 3 + [1e-10] * 3)
    sol = solve_ivp(
        rhs, (0.0, t_end_s), np.concatenate([r0, v0]), method="DOP853", rtol=1e-12, atol=atol
    )
    assert sol.success, sol.message
    return sol.y[:3, -1]


# ------------------------------------------------------------------------------ pole


def test_pole_agrees_with_erfa_and_is_the_itrs_z_axis():
    # Both implement IAU 2006 precession + IAU 2000A nutation; measured difference
    # <= 0.012 mas over 1950-2050. 0.1 mas (5e-10 rad) is below 1e-4 m per LEO orbit.
    offsets = np.arange(0.0, 40.0 * 86_400.0, 3 * 86_400.0)
    for epoch in ("2000-01-01T12:00:00Z", EPOCH_2025, EPOCH_2050):
        times = eo.times_after(epoch, offsets)
        pole = eo.pole_gcrs(times)
        ref = erfa_pole(epoch, offsets)
        angle = np.linalg.norm(np.cross(pole, ref), axis=1)
        assert np.all(angle < 0.1 * MAS_RAD), angle / MAS_RAD
        R = eo.R_gcrs_from_itrs(times)
        np.testing.assert_allclose(R[:, :, 2], pole, rtol=0, atol=1e-15)
        np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape),
                                   rtol=0, atol=1e-14)  # fmt: skip


def test_pole_offset_from_gcrs_z_grows_with_precession():
    # About 2004 arcsec per century along x (IERS Conventions 2010, Eq. 5.16, X series),
    # so 2.4e-3 rad at 2025 and 4.9e-3 rad at 2050, plus nutation (< 1e-4 rad).
    for epoch, expected_rad in ((EPOCH_2025, 2.44e-3), (EPOCH_2050, 4.87e-3)):
        p = eo.pole_gcrs(parse_epoch_utc(epoch))[0]
        assert math.acos(p[2]) == pytest.approx(expected_rad, abs=1e-4)


def test_pole_interpolation_error_is_negligible():
    # Hourly nodes, linear interpolation, 30 days: measured 4e-11 rad at most.
    span = 30.0 * 86_400.0
    track = eo.pole_track(EPOCH_2025, span)
    t = np.linspace(0.0, span, 4001) + 37.0  # off the nodes, a bit past the end too
    t[-1] = span
    direct = eo.pole_gcrs(eo.times_after(EPOCH_2025, t))
    interpolated = track.at(t)
    assert np.max(np.linalg.norm(np.cross(direct, interpolated), axis=1)) < 1e-10
    scalar = track.scalar_function()
    np.testing.assert_allclose([scalar(s) for s in t[::50]], interpolated[::50], rtol=0,
                               atol=1e-15)  # fmt: skip
    # Cached: the same epoch and span give the same node array.
    assert eo.pole_track(parse_epoch_utc(EPOCH_2025), span).nodes_gcrs is track.nodes_gcrs


# ---------------------------------------------------------------------- acceleration


def zonal_potential(r: np.ndarray, pole: np.ndarray, degree: int) -> float:
    """The zonal part of V = -mu/r [1 - sum J_n (R/r)^n P_n(u)], J/kg (a = -grad V)."""
    rn = float(np.linalg.norm(r))
    u = float(r @ pole) / rn
    legendre = {
        2: (3 * u**2 - 1) / 2,
        3: (5 * u**3 - 3 * u) / 2,
        4: (35 * u**4 - 30 * u**2 + 3) / 8,
    }
    coeff = {2: J2, 3: J3, 4: J4}
    ratio = EARTH_EQUATORIAL_RADIUS_M / rn
    series = sum(coeff[n] * ratio**n * legendre[n] for n in range(2, degree + 1))
    return MU_EARTH_M3_S2 / rn * series


@pytest.mark.parametrize("degree", [2, 3, 4])
def test_zonal_acceleration_is_minus_the_potential_gradient(degree):
    rng = np.random.default_rng(15 + degree)
    for _ in range(5):
        r = rng.normal(size=3)
        r *= rng.uniform(6.6e6, 4.2e7) / np.linalg.norm(r)
        pole = rng.normal(size=3)
        pole /= np.linalg.norm(pole)
        h = 1e-4 * np.linalg.norm(r)  # central differences: truncation ~(h/r)^2 = 1e-8
        grad = np.array([
            (zonal_potential(r + h * e, pole, degree) - zonal_potential(r - h * e, pole, degree))
            / (2 * h)
            for e in np.eye(3)
        ])  # fmt: skip
        ours = gravity_acceleration_m_s2(r, pole_gcrs=pole, max_zonal_degree=degree)
        point_mass = gravity_acceleration_m_s2(r, j2=False)
        perturbation = ours - point_mass
        np.testing.assert_allclose(perturbation, -grad, rtol=0,
                                   atol=1e-6 * np.linalg.norm(perturbation))  # fmt: skip


def test_gcrs_z_pole_reproduces_the_old_formula():
    r = np.array([4.0e6, -3.0e6, 4.5e6])
    old = gravity_acceleration_m_s2(r)
    np.testing.assert_allclose(gravity_acceleration_m_s2(r, pole_gcrs=[0.0, 0.0, 1.0]), old,
                               rtol=1e-14, atol=0)  # fmt: skip
    x, y, z = r
    rn = np.linalg.norm(r)
    s = 5 * z * z / rn**2
    f = -1.5 * J2 * MU_EARTH_M3_S2 * EARTH_EQUATORIAL_RADIUS_M**2 / rn**5
    textbook = -MU_EARTH_M3_S2 * r / rn**3 + f * np.array([x * (1 - s), y * (1 - s), z * (3 - s)])
    np.testing.assert_allclose(old, textbook, rtol=1e-14, atol=0)


# ----------------------------------------------------------------------- propagation


@pytest.mark.parametrize("method", ["rk4", "dop853"])
def test_true_pole_j2_matches_an_independent_integration(method):
    # Measured: 2e-5 m (RK4 1 s) and 1e-6 m (DOP853) after one orbit; the budget is 1 m.
    el = leo()
    r0, v0 = state_from_elements(el)
    period = orbital_period_s(el.semi_major_axis_m)
    reference = oracle_true_pole_j2(EPOCH_2025, r0, v0, period)
    r, _ = propagate(r0, v0, [period], epoch=EPOCH_2025, method=method)
    assert np.linalg.norm(r[0] - reference) < ONE_M


def test_pole_follows_time_over_a_day():
    # Over a day the pole moves 3.8e-7 rad; holding it at its epoch value would leave
    # 0.19 m against the oracle. Measured with the interpolated pole: 1.4e-4 m.
    r0, v0 = state_from_elements(leo())
    reference = oracle_true_pole_j2(EPOCH_2025, r0, v0, 86_400.0)
    r, _ = propagate(r0, v0, [86_400.0], epoch=EPOCH_2025)
    assert np.linalg.norm(r[0] - reference) < ONE_CM


def test_default_axis_follows_the_epoch():
    el = leo()
    r0, v0 = state_from_elements(el)
    period = orbital_period_s(el.semi_major_axis_m)
    times = [0.5 * period, period]
    with_epoch = propagate(r0, v0, times, epoch=EPOCH_2025)
    explicit = propagate(r0, v0, times, epoch=parse_epoch_utc(EPOCH_2025), j2_axis="true_pole")
    np.testing.assert_array_equal(with_epoch[0], explicit[0])
    without = propagate(r0, v0, times)
    gcrs_z = propagate(r0, v0, times, epoch=EPOCH_2025, j2_axis="gcrs_z")
    np.testing.assert_array_equal(without[0], gcrs_z[0])
    # Without J2 the axis does not matter.
    two_body = propagate(r0, v0, times, j2=False, epoch=EPOCH_2025)
    np.testing.assert_array_equal(two_body[0], propagate(r0, v0, times, j2=False)[0])


@pytest.mark.parametrize(
    ("epoch", "issue_m"),
    [(EPOCH_2025, 435.0), (EPOCH_2050, 853.0)],
)
def test_gcrs_z_approximation_error_after_one_orbit(epoch, issue_m):
    # The issue's figures for this orbit: 435 m at 2025, 853 m at 2050 (measured here:
    # 430 m and 862 m). The offset grows with the pole's precession from GCRS z.
    el = sun_synchronous()
    r0, v0 = state_from_elements(el)
    period = orbital_period_s(el.semi_major_axis_m)
    true_pole, _ = propagate(r0, v0, [period], epoch=epoch)
    gcrs_z, _ = propagate(r0, v0, [period], j2_axis="gcrs_z")
    difference = float(np.linalg.norm(true_pole[0] - gcrs_z[0]))
    assert difference == pytest.approx(issue_m, rel=0.2)


def test_j3_j4_flag_changes_the_orbit_by_the_expected_order():
    # J3 and J4 are ~1e-3 of J2: tens to hundreds of metres after one orbit.
    el = leo()
    r0, v0 = state_from_elements(el)
    period = orbital_period_s(el.semi_major_axis_m)
    base, _ = propagate(r0, v0, [period], epoch=EPOCH_2025)
    for degree in (3, 4):
        r, _ = propagate(r0, v0, [period], epoch=EPOCH_2025, max_zonal_degree=degree)
        assert 10.0 < np.linalg.norm(r[0] - base[0]) < 1000.0


def test_true_pole_errors_teach():
    r0, v0 = state_from_elements(leo())
    with pytest.raises(SatsightError, match="epoch"):
        propagate(r0, v0, [60.0], j2_axis="true_pole")
    with pytest.raises(SatsightError, match="j2_axis"):
        propagate(r0, v0, [60.0], j2_axis="itrs")
    with pytest.raises(SatsightError, match="max_zonal_degree"):
        propagate(r0, v0, [60.0], max_zonal_degree=5)
    with pytest.raises(SatsightError, match="ISO"):
        propagate(r0, v0, [60.0], epoch="tomorrow")
    with pytest.raises(SatsightError, match="skyfield Time"):
        propagate(r0, v0, [60.0], epoch=2025.5)
