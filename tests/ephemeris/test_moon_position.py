"""The Moon's (and the Sun's) geometric GCRS position against astropy on the same DE421.

Oracle: astropy's ``get_body_barycentric`` reading the very ``de421.bsp`` file that
satsight uses, through jplephem (a separate SPK reader from skyfield's), at astropy
``Time`` objects built on TDB from skyfield's own Julian dates. The geometric geocentric
vector is then ``body(t) - earth(t)``. Since the data are the same, the tolerance's basis
is the arithmetic of the two readers and the TDB split: measured agreement 2e-5 m
(5e-14 rad); the tests allow 1 m and 1 mas, far inside the 1 arcsec required of the
Moon's position and far below the 35-41 km (6-17 arcsec) that a light-time-only position
is off by. No network: IERS auto-download is off and no UTC conversion happens in astropy.
"""

from __future__ import annotations

import numpy as np
import pytest

from satsight.ephemeris import sun_moon
from satsight.ephemeris.time import parse_epoch_utc, skyfield_data_dir
from tolerances import ARCSEC_RAD, MAS_RAD

ONE_M = 1.0
KM = 1e3

EPOCHS = (
    "1950-02-14T00:00:00Z",
    "2000-01-01T12:00:00Z",
    "2010-06-21T00:00:00Z",
    "2025-03-20T12:00:00Z",
    "2025-06-21T06:00:00Z",
    "2033-11-05T18:45:30Z",
    "2050-12-31T23:00:00Z",
)


@pytest.fixture(scope="module")
def astropy_de421():
    """(Time, get_body_barycentric, u, path) with downloads off and the bundled DE421."""
    pytest.importorskip("jplephem")
    from astropy.utils import iers

    with iers.conf.set_temp("auto_download", False):
        import astropy.units as u
        from astropy.coordinates import get_body_barycentric
        from astropy.time import Time

        yield Time, get_body_barycentric, u, str(skyfield_data_dir() / sun_moon.EPHEMERIS_FILE)


def _oracle_geometric_m(astropy_de421, body: str, epochs) -> np.ndarray:
    Time, get_body_barycentric, u, path = astropy_de421
    ts = [parse_epoch_utc(e) for e in epochs]
    at = Time(
        [float(t.whole) for t in ts], [float(t.tdb_fraction) for t in ts], format="jd", scale="tdb"
    )
    target = get_body_barycentric(body, at, ephemeris=path).xyz.to_value(u.m).T
    earth = get_body_barycentric("earth", at, ephemeris=path).xyz.to_value(u.m).T
    return target - earth


def _ours_m(position, epochs) -> np.ndarray:
    return np.vstack([position(parse_epoch_utc(e)) for e in epochs])


def _angle_rad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


@pytest.mark.parametrize(
    ("body", "position"),
    [("moon", sun_moon.moon_position_gcrs_m), ("sun", sun_moon.sun_position_gcrs_m)],
)
def test_geometric_position_matches_astropy_on_the_same_kernel(astropy_de421, body, position):
    ours = _ours_m(position, EPOCHS)
    oracle = _oracle_geometric_m(astropy_de421, body, EPOCHS)
    assert np.all(np.linalg.norm(ours - oracle, axis=1) < ONE_M)
    assert np.all(_angle_rad(ours, oracle) < MAS_RAD)


def test_moon_is_not_the_light_time_only_position(astropy_de421):
    # The former definition (skyfield's observe: light time in the barycentric frame, no
    # aberration) sat 35-41 km behind, along the Earth's orbital velocity x 1.3 s.
    eph = sun_moon.ephemeris()
    ours = _ours_m(sun_moon.moon_position_gcrs_m, EPOCHS)
    ts = [parse_epoch_utc(e) for e in EPOCHS]
    astrometric = np.vstack([eph["earth"].at(t).observe(eph["moon"]).position.m for t in ts])
    offset_km = np.linalg.norm(ours - astrometric, axis=1) / KM
    assert np.all((offset_km > 30.0) & (offset_km < 45.0)), offset_km
    # ... and the geometric one is what astropy gives.
    oracle = _oracle_geometric_m(astropy_de421, "moon", EPOCHS)
    assert np.all(_angle_rad(ours, oracle) < ARCSEC_RAD)
