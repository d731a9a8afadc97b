"""CCSDS OEM: writer/reader round trip, interpolation error against closed-form bounds, and
the strict checks.

The truth is a circular Keplerian orbit, whose every Cartesian component is r cos(w t + c):
its k-th derivative is bounded by r w^k (as a vector norm too), so the interpolation error
bounds are exact: Lagrange on n nodes, |e| <= r w^n / n! * max prod |t - t_i|; Hermite on m
nodes (values and derivatives), |e| <= r w^(2m) / (2m)! * max prod (t - t_i)^2. The written
file rounds positions to 1 mm and velocities to 1 um/s; that rounding, amplified by the
interpolation's Lebesgue constant, is added to the bound.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from satsight.ephemeris.oem import format_oem, parse_oem, read_oem
from satsight.ephemeris.orbits import MU_EARTH_M3_S2
from satsight.ephemeris.sun_moon import gcrs_from_eme2000
from satsight.ephemeris.time import timescale
from satsight.ephemeris.tle import read_tle_file, select_orbit
from satsight.errors import SatsightError

RADIUS_M = 7000e3
OMEGA = math.sqrt(MU_EARTH_M3_S2 / RADIUS_M**3)
INCLINATION = 0.9
ROUNDING_M = 0.5e-3 * math.sqrt(3.0)  # position written to 1 mm per component
ROUNDING_M_S = 0.5e-6 * math.sqrt(3.0)


def _truth(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    phase = OMEGA * t_s
    ci, si = math.cos(INCLINATION), math.sin(INCLINATION)
    r = RADIUS_M * np.stack([np.cos(phase), np.sin(phase) * ci, np.sin(phase) * si], -1)
    v = RADIUS_M * OMEGA * np.stack([-np.sin(phase), np.cos(phase) * ci, np.cos(phase) * si], -1)
    return r, v


def _times(seconds: np.ndarray):
    return timescale().utc(2025, 6, 21, 6, 0, seconds)


def _write(step_s: float, span_s: float, interpolation: str, degree: int) -> str:
    seconds = np.arange(0.0, span_s + 0.5 * step_s, step_s)
    r, v = _truth(seconds)
    return format_oem(
        _times(seconds), r, v, object_name="TEST", object_id="2025-001A",
        interpolation=interpolation, degree=degree,
    )  # fmt: skip


def _node_product_max(count: int, power: int) -> float:
    """max over s in [0, count-1] of prod_i |s - i|^power (nodes at unit spacing)."""
    s = np.linspace(0.0, count - 1.0, 20001)
    return float(np.max(np.prod(np.abs(s[:, None] - np.arange(count)) ** power, axis=1)))


def _lebesgue(count: int) -> float:
    """The Lebesgue constant of Lagrange interpolation on ``count`` equispaced nodes."""
    s = np.linspace(0.0, count - 1.0, 20001)
    total = np.zeros_like(s)
    for j in range(count):
        w = np.ones_like(s)
        for k in range(count):
            if k != j:
                w *= (s - k) / (j - k)
        total += np.abs(w)
    return float(total.max())


@pytest.mark.parametrize(("step_s", "degree"), [(60.0, 3), (300.0, 7), (120.0, 5)])
def test_lagrange_error_within_bound(step_s: float, degree: int) -> None:
    span = 3 * 3600.0
    ephemeris = parse_oem(_write(step_s, span, "LAGRANGE", degree))
    query = np.linspace(0.0, span, 1501)
    r, v = ephemeris.state_gcrs(_times(query))
    r_true, v_true = _truth(query)
    n = degree + 1
    geometric = _node_product_max(n, 1) * step_s**n / math.factorial(n)
    bound_r = RADIUS_M * OMEGA**n * geometric + ROUNDING_M * _lebesgue(n)
    bound_v = RADIUS_M * OMEGA ** (n + 1) * geometric + ROUNDING_M_S * _lebesgue(n)
    err_r = np.linalg.norm(r - r_true, axis=1).max()
    err_v = np.linalg.norm(v - v_true, axis=1).max()
    assert err_r <= bound_r
    assert err_v <= bound_v
    # The bound is not vacuous: the error reaches a fair part of it when truncation rules.
    if RADIUS_M * OMEGA**n * geometric > 1.0:
        assert err_r > 0.2 * bound_r


@pytest.mark.parametrize(("step_s", "degree"), [(60.0, 3), (300.0, 7)])
def test_hermite_error_within_bound(step_s: float, degree: int) -> None:
    span = 3 * 3600.0
    ephemeris = parse_oem(_write(step_s, span, "HERMITE", degree))
    query = np.linspace(0.0, span, 1501)
    r, _ = ephemeris.state_gcrs(_times(query))
    r_true, _ = _truth(query)
    m = math.ceil((degree + 1) / 2)
    truncation = (
        RADIUS_M
        * OMEGA ** (2 * m)
        * _node_product_max(m, 2)
        * step_s ** (2 * m)
        / math.factorial(2 * m)
    )
    # Rounding: the data enter through the Hermite basis; its size is below that of the
    # Lagrange basis on 2m nodes spread over the same span, so that constant bounds it.
    bound = truncation + (ROUNDING_M + ROUNDING_M_S * step_s) * _lebesgue(2 * m)
    err = np.linalg.norm(r - r_true, axis=1).max()
    assert err <= bound
    if truncation > 1.0:
        assert err > 0.2 * bound


def test_round_trip_at_the_nodes_and_bounds() -> None:
    text = _write(60.0, 600.0, "LAGRANGE", 7)
    ephemeris = parse_oem(text)
    seconds = np.arange(0.0, 601.0, 60.0)
    r, v = ephemeris.state_gcrs(_times(seconds))
    r_true, v_true = _truth(seconds)
    assert np.abs(r - r_true).max() <= 0.5e-3 + 1e-9
    assert np.abs(v - v_true).max() <= 0.5e-6 + 1e-12
    assert ephemeris.useable_start_utc == "2025-06-21T06:00:00.000000Z"
    assert ephemeris.object_name == "TEST"


def test_times_outside_are_refused() -> None:
    ephemeris = parse_oem(_write(60.0, 600.0, "LAGRANGE", 7))
    with pytest.raises(SatsightError, match=r"05:59:59.000Z \(UTC\) lies outside"):
        ephemeris.state_gcrs(_times(np.array([-1.0])))
    with pytest.raises(SatsightError, match=r"lies outside the ephemeris's useable span"):
        ephemeris.state_gcrs(_times(np.array([300.0, 601.0])))


def test_useable_span_and_segments() -> None:
    text = _write(60.0, 600.0, "LAGRANGE", 3)
    text = text.replace(
        "STOP_TIME = 2025-06-21T06:10:00.000000",
        "USEABLE_START_TIME = 2025-06-21T06:01:00\n"
        "USEABLE_STOP_TIME = 2025-06-21T06:09:00\nSTOP_TIME = 2025-06-21T06:10:00.000000",
    )
    ephemeris = parse_oem(text)
    ephemeris.state_gcrs(_times(np.array([60.0, 540.0])))
    with pytest.raises(SatsightError, match=r"outside"):
        ephemeris.state_gcrs(_times(np.array([30.0])))


def test_eme2000_is_turned_into_gcrs_and_covariance_skipped() -> None:
    text = _write(60.0, 600.0, "LAGRANGE", 7).replace("REF_FRAME = GCRF", "REF_FRAME = EME2000")
    text += "COVARIANCE_START\nEPOCH = 2025-06-21T06:00:00\n1.0\nCOVARIANCE_STOP\n"
    ephemeris = parse_oem(text)
    r, _ = ephemeris.state_gcrs(_times(np.array([120.0])))
    r_file, _ = _truth(np.array([120.0]))
    assert np.allclose(r, gcrs_from_eme2000(r_file), atol=1e-3)
    assert np.linalg.norm(r - r_file) > 0.5  # the 23 mas bias: ~0.8 m at 7000 km


def test_day_of_year_epochs_and_tai() -> None:
    text = _write(60.0, 600.0, "LAGRANGE", 7)
    doy = text.replace("2025-06-21T", "2025-172T")
    a = parse_oem(text).state_gcrs(_times(np.array([90.0])))[0]
    b = parse_oem(doy).state_gcrs(_times(np.array([90.0])))[0]
    assert np.allclose(a, b, atol=1e-9)
    tai = parse_oem(text.replace("TIME_SYSTEM = UTC", "TIME_SYSTEM = TAI"))
    # The same labels read as TAI are 37 s earlier in UTC: the whole file moves.
    assert tai.useable_start_utc == "2025-06-21T05:59:23.000000Z"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("CENTER_NAME = EARTH", "CENTER_NAME = MOON"), r"only EARTH"),
        (("REF_FRAME = GCRF", "REF_FRAME = ITRF"), r"REF_FRAME 'ITRF' is not supported"),
        (("TIME_SYSTEM = UTC", "TIME_SYSTEM = UT1"), r"TIME_SYSTEM 'UT1' is not supported"),
        (("INTERPOLATION = LAGRANGE", "INTERPOLATION = SPLINE"), r"INTERPOLATION 'SPLINE'"),
        (("OBJECT_ID = 2025-001A\n", ""), r"metadata lacks OBJECT_ID"),
        (("ORIGINATOR = satsight", "ORIGINATOR = satsight\nFOO = 1"), r"line 4: unknown header"),
        (("7000.000000 0.000000", "7000.000000"), r"line 17: a state line holds"),
        (("2025-06-21T06:01:00.000000 ", "2025-06-21T05:59:30.000000 "), r"increase strictly"),
    ],
)
def test_malformed_messages(edit: tuple[str, str], message: str) -> None:
    text = _write(60.0, 600.0, "LAGRANGE", 7)
    assert edit[0] in text
    with pytest.raises(SatsightError, match=message):
        parse_oem(text.replace(edit[0], edit[1], 1))


def test_bundled_example_oem_matches_its_tle() -> None:
    folder = Path(str(resources.files("satsight") / "examples"))
    ephemeris = read_oem(folder / "iss_2019-12-09.oem")
    iss = select_orbit(read_tle_file(folder / "example_satellites.tle"), "ISS (ZARYA)", "x")
    seconds = np.linspace(0.0, 7200.0, 97)
    times = timescale().utc(2019, 12, 9, 16, 40, seconds)
    r, _ = ephemeris.state_gcrs(times)
    r_sgp4, _ = iss.state_gcrs(times)
    # 60 s steps, degree 7: truncation ~1e-5 m; the 1 mm rounding dominates.
    assert np.linalg.norm(r - r_sgp4, axis=1).max() < 0.01
