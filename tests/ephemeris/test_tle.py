"""TLE / OMM parsing and SGP4 positions, checked against an independent route.

The reference is python-sgp4's ``Satrec`` evaluated directly (TEME, km) and rotated to GCRS
by astropy (TEME -> ITRS -> GCRS, IAU 2006/2000A with IERS-B Earth orientation), while the
code under test goes through skyfield's EarthSatellite and skyfield's own TEME rotation
(its precession-nutation model). Both evaluate the same SGP4 theory, so what differs is only
the frame rotation: the models agree to well under a milliarcsecond, i.e. millimetres at
LEO distances. ONE_M (1 m, 1.4e-7 rad or 30 mas at 7000 km) is the issue's tolerance and
leaves room for any reasonable difference of nutation models; the measured gap is ~0.3 mm.
"""

from __future__ import annotations

import json
import logging
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from iss_elements import ISS_1, ISS_2, ISS_OMM_FIELDS
from satsight.ephemeris.omm import parse_omm
from satsight.ephemeris.sgp4_orbit import MAX_AGE_DAYS
from satsight.ephemeris.time import epoch_times
from satsight.ephemeris.tle import parse_tle, read_tle_file, select_orbit, tle_checksum
from satsight.errors import SatsightError
from tolerances import ONE_MM_S

ONE_M = 1.0

VANGUARD_1 = "1 00005U 58002B   00179.78495062  .00000023  00000-0  28098-4 0  4753"
VANGUARD_2 = "2 00005  34.2682 348.7242 1859667 331.7664  19.3264 10.82419157413667"


def _reference_gcrs(line1: str, line2: str, times) -> tuple[np.ndarray, np.ndarray]:
    """python-sgp4 in TEME, rotated to GCRS by astropy (no network)."""
    from astropy.utils import iers

    iers.conf.auto_download = False
    import astropy.units as u
    from astropy.coordinates import GCRS, TEME, CartesianDifferential, CartesianRepresentation
    from astropy.time import Time as AstropyTime
    from sgp4.api import WGS72, Satrec

    satrec = Satrec.twoline2rv(line1, line2, WGS72)
    at = AstropyTime(
        np.asarray(times.whole), np.asarray(times.tt_fraction), format="jd", scale="tt"
    )
    utc = at.utc
    error, r_km, v_km_s = satrec.sgp4_array(utc.jd1, utc.jd2)
    assert not np.any(error)
    teme = TEME(
        CartesianRepresentation(
            r_km.T * u.km, differentials=CartesianDifferential(v_km_s.T * u.km / u.s)
        ),
        obstime=at,
    )
    gcrs = teme.transform_to(GCRS(obstime=at))
    r = gcrs.cartesian.xyz.to_value(u.m).T
    v = gcrs.velocity.d_xyz.to_value(u.m / u.s).T
    return r, v


@pytest.mark.parametrize(("line1", "line2"), [(ISS_1, ISS_2), (VANGUARD_1, VANGUARD_2)])
def test_sgp4_gcrs_matches_sgp4_and_astropy(line1: str, line2: str) -> None:
    orbit = parse_tle([line1, line2])[0]
    times = epoch_times(orbit.epoch_utc, np.linspace(-2 * 86400.0, 2 * 86400.0, 17))
    r, v = orbit.state_gcrs(times)
    r_ref, v_ref = _reference_gcrs(line1, line2, times)
    assert np.max(np.linalg.norm(r - r_ref, axis=1)) < ONE_M
    assert np.max(np.linalg.norm(v - v_ref, axis=1)) < ONE_MM_S


def test_tle_fields() -> None:
    orbit = parse_tle(["0 ISS (ZARYA)", ISS_1, ISS_2])[0]
    assert orbit.name == "ISS (ZARYA)"
    assert orbit.catalog_number == "25544"
    assert orbit.epoch_utc.startswith("2019-12-09T16:38:29.36")
    # 15.50103472 rev/day -> 5573.8 s; the mean semi-major axis about 6795 km.
    assert orbit.period_s == pytest.approx(86400.0 / 15.50103472, rel=1e-9)
    assert orbit.mean_semi_major_axis_m == pytest.approx(6.795e6, rel=1e-3)


def test_checksum_of_published_lines() -> None:
    for line in (ISS_1, ISS_2, VANGUARD_1, VANGUARD_2):
        assert tle_checksum(line) == int(line[68])


def test_wrong_checksum_names_line_and_column() -> None:
    bad = ISS_2[:68] + "3"
    with pytest.raises(SatsightError, match=r"line 3: TLE line 2, column 69: checksum 3"):
        parse_tle(["ISS", ISS_1, bad], source="iss.tle")


def test_bad_field_names_its_columns() -> None:
    bad = ISS_2[:8] + "51.6x39" + ISS_2[15:]
    bad = bad[:68] + str(tle_checksum(bad))
    with pytest.raises(SatsightError, match=r"line 2: TLE line 2, columns 9-16 \(inclination"):
        parse_tle([ISS_1, bad])


def test_short_line_and_missing_line_2() -> None:
    with pytest.raises(SatsightError, match=r"line 1: TLE line 1 must be 69 columns"):
        parse_tle([ISS_1[:60], ISS_2])
    with pytest.raises(SatsightError, match=r"line 1: TLE line 1 is not followed by its line 2"):
        parse_tle([ISS_1])
    with pytest.raises(SatsightError, match=r"catalogue number '00005' differs"):
        parse_tle([ISS_1, VANGUARD_2])


def test_age_warning_and_refusal(caplog: pytest.LogCaptureFixture) -> None:
    orbit = parse_tle([ISS_1, ISS_2])[0]
    with caplog.at_level(logging.WARNING, logger="satsight.ephemeris.sgp4_orbit"):
        orbit.state_gcrs(epoch_times(orbit.epoch_utc, [8 * 86400.0]))
    assert "SGP4 accuracy degrades" in caplog.text
    with pytest.raises(SatsightError, match=r"refused beyond 30 days"):
        orbit.state_gcrs(epoch_times(orbit.epoch_utc, [-(MAX_AGE_DAYS + 1) * 86400.0]))


def _kvn(fields: dict[str, str]) -> str:
    header = [
        "CCSDS_OMM_VERS = 2.0",
        "COMMENT written by the test",
        "CREATION_DATE = 2019-12-10T00:00:00",
        "ORIGINATOR = TEST",
        "CENTER_NAME = EARTH",
        "REF_FRAME = TEME",
        "TIME_SYSTEM = UTC",
        "MEAN_ELEMENT_THEORY = SGP4",
    ]
    units = {"MEAN_MOTION": " [rev/day]", "INCLINATION": " [deg]"}
    return "\n".join(header + [f"{k} = {v}{units.get(k, '')}" for k, v in fields.items()])


def _xml(fields: dict[str, str]) -> str:
    meta = ("OBJECT_NAME", "OBJECT_ID")
    body = "".join(f"<{k}>{v}</{k}>" for k, v in fields.items() if k not in meta)
    head = "".join(f"<{k}>{fields[k]}</{k}>" for k in meta)
    return (
        '<?xml version="1.0"?><ndm><omm id="CCSDS_OMM_VERS" version="2.0"><header/><body>'
        f"<segment><metadata>{head}<CENTER_NAME>EARTH</CENTER_NAME><REF_FRAME>TEME</REF_FRAME>"
        f"<TIME_SYSTEM>UTC</TIME_SYSTEM></metadata><data><meanElements>{body}</meanElements>"
        "</data></segment></body></omm></ndm>"
    )


def _csv(fields: dict[str, str]) -> str:
    return ",".join(fields) + "\n" + ",".join(fields.values()) + "\n"


@pytest.mark.parametrize("form", ["kvn", "xml", "json", "csv"])
def test_omm_forms_match_the_tle(form: str) -> None:
    text = {
        "kvn": _kvn,
        "xml": _xml,
        "json": lambda f: json.dumps([f]),
        "csv": _csv,
    }[form](ISS_OMM_FIELDS)
    omm = parse_omm(text)[0]
    tle = parse_tle([ISS_1, ISS_2])[0]
    assert omm.name == "ISS (ZARYA)"
    times = epoch_times(tle.epoch_utc, np.linspace(0.0, 86400.0, 7))
    r_omm, _ = omm.state_gcrs(times)
    r_tle, _ = tle.state_gcrs(times)
    # The OMM epoch is the TLE's day fraction rounded to 1 us: 7.7 km/s x 1 us ~ 1 cm.
    assert np.max(np.linalg.norm(r_omm - r_tle, axis=1)) < 0.05


def test_omm_wrong_frame_and_missing_key() -> None:
    with pytest.raises(SatsightError, match=r"REF_FRAME = 'EME2000'; SGP4 elements need TEME"):
        parse_omm(_kvn(ISS_OMM_FIELDS).replace("REF_FRAME = TEME", "REF_FRAME = EME2000"))
    fields = {k: v for k, v in ISS_OMM_FIELDS.items() if k != "BSTAR"}
    with pytest.raises(SatsightError, match=r"missing OMM keyword\(s\) BSTAR"):
        parse_omm(json.dumps(fields))


def test_bundled_example_tles_and_selection() -> None:
    path = Path(str(resources.files("satsight") / "examples" / "example_satellites.tle"))
    orbits = read_tle_file(path)
    assert [o.name for o in orbits] == ["ISS (ZARYA)", "ISS 2014", "VANGUARD 1"]
    with pytest.raises(SatsightError, match=r"holds 3 element sets"):
        select_orbit(orbits, None, str(path))
    assert select_orbit(orbits, "vanguard 1", str(path)).catalog_number == "00005"
    # Two sets of 25544: the number picks the latest epoch.
    assert select_orbit(orbits, 25544, str(path)).name == "ISS (ZARYA)"
