"""Offline epochs, Sun and Moon positions and the J2000 frame bias, against independent oracles.

Oracle: astropy's built-in ephemeris (ERFA ``epv00`` for the Earth and the Sun, ERFA
``moon98`` for the Moon), which shares no code or data with skyfield's DE421. Astropy never
touches the network here: IERS auto-download is off and every astropy ``Time`` is built on
TDB from skyfield's own Julian dates (for the ephemeris comparison) or on UTC only for
dates up to 2025 (for the time-scale comparison), so neither its IERS tables nor its
"dubious year" leap-second warnings for far-future UTC come into play.
"""

from __future__ import annotations

import math
import socket
import urllib.request

import numpy as np
import pytest

from satsight.ephemeris import sun_moon, time
from satsight.errors import SatsightError
from tolerances import ARCSEC_RAD, MAS_RAD

C_M_S = 299_792_458.0

# Epochs spread over 2000-2050 (UTC), inside DE421's span.
EPOCHS = (
    "2000-01-01T12:00:00Z",
    "2003-07-15T03:20:00Z",
    "2010-06-21T00:00:00Z",
    "2017-01-01T00:00:00Z",
    "2025-03-20T12:00:00Z",
    "2033-11-05T18:45:30Z",
    "2042-02-28T06:00:00Z",
    "2050-12-31T23:00:00Z",
)
# Astropy's UTC handling flags years more than a few years past its leap-second table as
# dubious (an ErfaWarning); UTC comparisons stay at or before 2025.
EPOCHS_UTC_SAFE = EPOCHS[:5]

# Oracle accuracy (ERFA documentation, Notes to eraEpv00 and eraMoon98):
# epv00 vs JPL DE405 over 1900-2100: heliocentric Earth position error at most 11.2 km,
# i.e. 0.015 arcsec and 7.5e-8 of 1 AU. moon98 vs ELP/MPP02 over 1950-2100: worst case
# 18.3 arcsec in geocentric direction and 31.7 km in position (8.9e-5 of the perigee
# distance 356,000 km).
SUN_DIRECTION_TOL_ARCSEC = 0.05
SUN_DISTANCE_REL_TOL = 1e-7
MOON_DIRECTION_TOL_ARCSEC = 20.0
MOON_DISTANCE_REL_TOL = 1e-4


@pytest.fixture(scope="module")
def astropy_offline():
    """Astropy with IERS downloads off; returns (Time, get_body_barycentric, get_body, u)."""
    from astropy.utils import iers

    with iers.conf.set_temp("auto_download", False):
        with iers.conf.set_temp("iers_degraded_accuracy", "ignore"):
            import astropy.units as u
            from astropy.coordinates import get_body, get_body_barycentric
            from astropy.time import Time

            yield Time, get_body_barycentric, get_body, u


def _times(epochs):
    return [time.parse_epoch_utc(e) for e in epochs]


def _astropy_tdb(Time, ts):
    # Same instants on both sides: skyfield's TDB Julian dates, handed to astropy as TDB.
    return Time(
        [float(t.whole) for t in ts], [float(t.tdb_fraction) for t in ts], format="jd", scale="tdb"
    )


def _oracle_geometric_m(astropy_offline, body, ts):
    """Geocentric geometric position: body(t) - earth(t), m, no light time, aberration or
    deflection: the definition ``sun_moon`` uses for both the Sun and the Moon."""
    Time, get_body_barycentric, _, u = astropy_offline
    at = _astropy_tdb(Time, ts)
    earth = get_body_barycentric("earth", at, ephemeris="builtin").xyz.to_value(u.m).T
    target = get_body_barycentric(body, at, ephemeris="builtin").xyz.to_value(u.m).T
    return target - earth


def _angle_arcsec(a, b):
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.arctan2(cross, np.sum(a * b, axis=-1)) / ARCSEC_RAD


def _stack(fn, ts):
    return np.vstack([fn(t) for t in ts])


# ---------------------------------------------------------------------------- time


@pytest.mark.parametrize(
    "text",
    [
        "2025-03-20T12:00:00.000000Z",
        "2000-01-01T11:58:55.816000Z",
        "2049-02-28T23:59:59.999999Z",
        "2016-12-31T23:59:60.500000Z",  # inside the last leap second
    ],
)
def test_iso_epoch_round_trip(text):
    assert time.format_epoch_utc(time.parse_epoch_utc(text)) == text


def test_optional_suffix_seconds_and_fraction():
    ref = time.parse_epoch_utc("2025-03-20T12:00:00Z")
    for text in ("2025-03-20T12:00:00", "2025-03-20T12:00", "2025-03-20T12:00:00+00:00"):
        t = time.parse_epoch_utc(text)
        assert (t.whole, t.tt_fraction) == (ref.whole, ref.tt_fraction)
    t = time.parse_epoch_utc("2025-03-20T12:00:00.125Z")
    dt_s = ((t.whole - ref.whole) + (t.tt_fraction - ref.tt_fraction)) * 86_400.0
    assert dt_s == pytest.approx(0.125, abs=1e-9)


@pytest.mark.parametrize(
    "bad",
    [
        "2025-13-01T00:00:00Z",
        "2025-02-29T00:00:00Z",
        "20250320T120000Z",
        "2025-03-20 12:00:00",
        "2025-03-20T12:00:00+01:00",
        "2025-03-20T24:00:00Z",
        "2025-03-20T23:59:60Z",  # no leap second that day
        "yesterday",
        42,
    ],
)
def test_bad_epoch_is_a_teaching_error(bad):
    with pytest.raises(SatsightError) as info:
        time.parse_epoch_utc(bad)
    msg = str(info.value)
    assert repr(bad) in msg
    assert "YYYY-MM-DDTHH:MM" in msg


def test_epoch_times_offsets_are_elapsed_seconds_across_a_leap_second():
    t = time.epoch_times("2016-12-31T23:59:59Z", [0.0, 1.0, 2.0])
    assert time.format_epoch_utc(t, places=0) == [
        "2016-12-31T23:59:59Z",
        "2016-12-31T23:59:60Z",
        "2017-01-01T00:00:00Z",
    ]


def test_epoch_times_keeps_microseconds_over_decades():
    offsets_s = np.array([-86_400.5, 0.0, 0.25, 40.0 * 365.25 * 86_400.0 + 0.000_001])
    t = time.epoch_times("2010-06-21T00:00:00.5Z", offsets_s)
    assert t.shape == (4,)
    elapsed_s = ((t.whole - t.whole[1]) + (t.tt_fraction - t.tt_fraction[1])) * 86_400.0
    np.testing.assert_allclose(elapsed_s, offsets_s, rtol=0.0, atol=1e-6)


def test_epoch_times_rejects_bad_offsets():
    with pytest.raises(SatsightError, match="offsets_s"):
        time.epoch_times("2025-03-20T12:00:00Z", [[0.0, 1.0]])
    with pytest.raises(SatsightError, match="offsets_s"):
        time.epoch_times("2025-03-20T12:00:00Z", [0.0, math.nan])


def test_utc_to_tt_agrees_with_astropy(astropy_offline):
    # Astropy's leap seconds come from ERFA / astropy-iers-data, not from skyfield.
    Time = astropy_offline[0]
    ts = _times(EPOCHS_UTC_SAFE)
    at = Time([e.removesuffix("Z") for e in EPOCHS_UTC_SAFE], scale="utc").tt
    for t, a in zip(ts, at, strict=True):
        diff_s = ((a.jd1 - t.whole) + (a.jd2 - t.tt_fraction)) * 86_400.0
        assert abs(diff_s) < 1e-6


# ----------------------------------------------------------------------- Sun, Moon


def test_shapes_units_and_dtype():
    t = time.epoch_times("2025-03-20T12:00:00Z", np.arange(5) * 600.0)
    sun = sun_moon.sun_position_gcrs_m(t)
    moon = sun_moon.moon_position_gcrs_m(t)
    assert sun.shape == moon.shape == (5, 3)
    assert sun.dtype == moon.dtype == np.float64
    assert sun_moon.sun_position_gcrs_m(time.parse_epoch_utc("2025-03-20T12:00:00Z")).shape == (
        1,
        3,
    )
    assert np.all(np.abs(np.linalg.norm(sun, axis=1) / sun_moon.AU_M - 1.0) < 0.02)
    assert np.all(np.abs(np.linalg.norm(moon, axis=1) - 3.85e8) < 0.25e8)


@pytest.mark.parametrize(
    ("body", "position", "direction_tol_arcsec", "distance_rel_tol"),
    [
        ("sun", sun_moon.sun_position_gcrs_m, SUN_DIRECTION_TOL_ARCSEC, SUN_DISTANCE_REL_TOL),
        ("moon", sun_moon.moon_position_gcrs_m, MOON_DIRECTION_TOL_ARCSEC, MOON_DISTANCE_REL_TOL),
    ],
)
def test_body_agrees_with_astropy_builtin(
    astropy_offline, body, position, direction_tol_arcsec, distance_rel_tol
):
    ts = _times(EPOCHS)
    ours = _stack(position, ts)
    oracle = _oracle_geometric_m(astropy_offline, body, ts)
    angle = _angle_arcsec(ours, oracle)
    rel = np.linalg.norm(ours, axis=1) / np.linalg.norm(oracle, axis=1) - 1.0
    assert np.all(angle < direction_tol_arcsec), angle
    assert np.all(np.abs(rel) < distance_rel_tol), rel


def test_geometric_not_apparent_differs_by_annual_aberration(astropy_offline):
    # astropy's get_body returns the apparent GCRS direction (aberration applied). The Sun
    # lies about 90 degrees from the Earth's velocity, so the two differ by the full
    # aberration v/c: 20.15-20.85 arcsec from aphelion to perihelion.
    Time, _, get_body, u = astropy_offline
    ts = _times(EPOCHS_UTC_SAFE)
    apparent = get_body("sun", _astropy_tdb(Time, ts), ephemeris="builtin")
    apparent_m = apparent.cartesian.xyz.to_value(u.m).T
    angle = _angle_arcsec(_stack(sun_moon.sun_position_gcrs_m, ts), apparent_m)
    assert np.all((angle > 20.0) & (angle < 21.0)), angle


@pytest.mark.parametrize(
    ("published_utc", "apparent_longitude_deg"),
    [
        # Equinoxes and solstices to the minute, as published by the US Naval Observatory
        # (Astronomical Applications Dept., "Earth's Seasons").
        ("2024-03-20T03:06:00Z", 0.0),
        ("2025-03-20T09:01:00Z", 0.0),
        ("2025-06-21T02:42:00Z", 90.0),
    ],
)
def test_equinox_and_solstice_instants(published_utc, apparent_longitude_deg):
    # Apparent ecliptic longitude of date from skyfield's precession-nutation (test only).
    # The Sun moves 2.4-2.6 arcsec per minute, so rounding to the minute allows 1.3 arcsec.
    from skyfield.framelib import ecliptic_frame

    eph = sun_moon.ephemeris()
    t = time.parse_epoch_utc(published_utc)
    _, lon, _ = eph["earth"].at(t).observe(eph["sun"]).apparent().frame_latlon(ecliptic_frame)
    diff_deg = (lon.degrees - apparent_longitude_deg + 180.0) % 360.0 - 180.0
    assert abs(diff_deg) * 3600.0 < 2.0


def test_sun_distance_spans_perihelion_to_aphelion():
    # Earth-Moon barycentre orbit at J2000: a = 1.000001 AU, e = 0.0167086 (Simon et al.,
    # A&A 282, 663, 1994), so 0.98329 AU at perihelion (early January) and 1.01671 AU at
    # aphelion (early July). The Earth's offset from the barycentre adds up to 4,700 km
    # (3.1e-5 AU); the Moon and planets perturb the orbit at a similar level.
    t = time.epoch_times("2025-01-01T00:00:00Z", np.arange(0.0, 365.0, 0.25) * 86_400.0)
    d_au = sun_moon.sun_distance_au(t)
    i_min, i_max = int(np.argmin(d_au)), int(np.argmax(d_au))
    assert d_au[i_min] == pytest.approx(0.98329, abs=1e-4)
    assert d_au[i_max] == pytest.approx(1.01671, abs=1e-4)
    assert 1 <= i_min / 4 <= 6  # January 2-7
    assert 181 <= i_max / 4 <= 188  # July 1-8


def test_outside_ephemeris_span_is_a_satsight_error():
    with pytest.raises(SatsightError, match=r"de421\.bsp"):
        sun_moon.sun_position_gcrs_m(time.parse_epoch_utc("2060-01-01T00:00:00Z"))


# ----------------------------------------------------------------- offline loading


def test_loading_never_touches_the_network(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("network access attempted")

    import skyfield.iokit

    monkeypatch.setattr(skyfield.iokit, "download", refuse)
    monkeypatch.setattr(skyfield.iokit, "urlopen", refuse, raising=False)
    monkeypatch.setattr(urllib.request, "urlopen", refuse)
    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    sun_moon.clear_cache()
    try:
        t = time.epoch_times("2025-03-20T12:00:00Z", [0.0, 60.0])
        assert sun_moon.moon_position_gcrs_m(t).shape == (2, 3)
        loader = time.skyfield_loader()
        assert loader.directory == str(time.skyfield_data_dir())
        assert loader.urls == {}
        assert (time.skyfield_data_dir() / sun_moon.EPHEMERIS_FILE).is_file()
    finally:
        sun_moon.clear_cache()


def test_missing_ephemeris_file_says_reinstall(tmp_path):
    with pytest.raises(SatsightError, match="reinstall skyfield-data"):
        sun_moon.load_ephemeris(tmp_path / "de421.bsp")


# ---------------------------------------------------------------------- frame bias


def test_frame_bias_is_a_23_mas_proper_rotation():
    b = sun_moon.eme2000_from_gcrs_matrix()
    np.testing.assert_allclose(b @ b.T, np.eye(3), rtol=0.0, atol=1e-15)
    assert np.linalg.det(b) == pytest.approx(1.0, abs=1e-15)
    axial = 0.5 * np.array([b[1, 2] - b[2, 1], b[2, 0] - b[0, 2], b[0, 1] - b[1, 0]])
    angle_mas = np.linalg.norm(axial) / MAS_RAD
    assert angle_mas == pytest.approx(math.sqrt(14.6**2 + 16.6170**2 + 6.8192**2), rel=1e-6)
    assert 23.0 < angle_mas < 23.3
    np.testing.assert_allclose(sun_moon.gcrs_from_eme2000_matrix(), b.T, rtol=0, atol=0)


def test_frame_bias_puts_the_j2000_pole_at_xi0_eta0():
    # IERS Conventions 2010, Ch. 5: xi0, eta0 are the GCRS coordinates of the J2000 mean pole.
    pole = sun_moon.gcrs_from_eme2000([0.0, 0.0, 1.0])
    # Exactly to first order; the product of rotations adds ~1e-6 mas of second order.
    np.testing.assert_allclose(pole[:2] / MAS_RAD, [-16.6170, -6.8192], rtol=0.0, atol=1e-5)


def test_frame_bias_matches_erfa_and_skyfield():
    import erfa
    from skyfield.framelib import ICRS_to_J2000

    b = sun_moon.eme2000_from_gcrs_matrix()
    rb, _, _ = erfa.bp00(2451545.0, 0.0)
    # ERFA derives xi0 from d_psi_bias sin(eps0); the rounding of xi0 is below 1 micro-arcsec.
    np.testing.assert_allclose(b, rb, rtol=0.0, atol=5e-12)
    # skyfield keeps only first-order off-diagonal terms: second order is ~1e-14.
    np.testing.assert_allclose(b, ICRS_to_J2000, rtol=0.0, atol=1e-13)


def test_frame_bias_vector_round_trip_and_shape_check():
    rng = np.random.default_rng(7)
    v = rng.normal(size=(4, 2, 3)) * 4.2e7
    w = sun_moon.eme2000_from_gcrs(v)
    assert w.shape == v.shape
    np.testing.assert_allclose(sun_moon.gcrs_from_eme2000(w), v, rtol=0.0, atol=1e-7)
    assert np.max(np.linalg.norm(w - v, axis=-1) / np.linalg.norm(v, axis=-1)) < 1.2e-7
    with pytest.raises(SatsightError, match="shape"):
        sun_moon.eme2000_from_gcrs([1.0, 2.0])
