"""The Earth's orientation in a frame at a known epoch: continents where they should be.

A target straight above a known latitude / longitude looks at nadir; the ray meets the
Earth body built as the pipeline builds it (fixed frame = ITRS from
``R_itrs_from_gcrs`` at the epoch, render frame = GCRS here), and the map's albedo there
must be land over the Sahara and Australia, ocean over the Pacific. The place is put in
GCRS by an independent, cruder model: a rotation about the pole by the Greenwich mean
sidereal time (Meeus, "Astronomical Algorithms", 2nd ed., Eq. 12.4, T^2 terms dropped),
ignoring precession since J2000 (0.35 deg in 2025), nutation and UT1 - UTC (< 0.9 s):
together < 0.5 deg, far inside the regions chosen (each > 5 deg from any coast). A
transposed rotation (R_gcrs_from_itrs where R_itrs_from_gcrs belongs) turns the Earth by
twice the sidereal angle the wrong way: at this epoch (sidereal time 268 deg) by 176 deg,
which puts the Sahara in the Pacific and the equatorial Pacific in Africa, and every
longitude off by 176 deg (checked by swapping the rotation's axes, outside this file).
"""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from satsight.constants import EARTH_MEAN_RADIUS_M
from satsight.ephemeris.earth_orientation import R_itrs_from_gcrs
from satsight.ephemeris.time import parse_epoch_utc
from satsight.lighting.earth_surface import (
    LAND_ALBEDO,
    OCEAN_ALBEDO,
    EarthSurfaceModel,
    earth_albedo_map,
)
from satsight.lighting.scene_bodies import earth_body

EPOCH_UTC = "2025-03-20T06:00:00Z"  # Greenwich mean sidereal time 268 deg
ALTITUDE_M = 500e3

PLACES = {
    # name: (geodetic latitude deg, east longitude deg, expected albedo)
    "sahara": (23.0, 12.0, LAND_ALBEDO),
    "australia": (-25.0, 134.0, LAND_ALBEDO),
    "pacific_equator": (0.0, -150.0, OCEAN_ALBEDO),
    "south_pacific": (-30.0, -120.0, OCEAN_ALBEDO),
}


def gmst_rad(when: datetime) -> float:
    """Greenwich mean sidereal time, rad (Meeus Eq. 12.4 without the T^2, T^3 terms)."""
    days = (when - datetime(2000, 1, 1, 12, tzinfo=UTC)).total_seconds() / 86_400.0
    return math.radians((280.46061837 + 360.98564736629 * days) % 360.0)


def place_gcrs_m(lat_deg: float, lon_deg: float, when: datetime) -> np.ndarray:
    lat, lon = math.radians(lat_deg), math.radians(lon_deg) + gmst_rad(when)
    r = EARTH_MEAN_RADIUS_M + ALTITUDE_M
    return r * np.array(
        [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
    )


@pytest.fixture(scope="module")
def clear_sky_map():
    return earth_albedo_map(EarthSurfaceModel(cloud_fraction=0.0, cloud_albedo=0.5))


@pytest.mark.parametrize("name", sorted(PLACES))
def test_nadir_sees_the_land_or_ocean_of_the_place_below(name, clear_sky_map):
    lat, lon, expected = PLACES[name]
    when = datetime.fromisoformat(EPOCH_UTC.replace("Z", "+00:00"))
    target_gcrs = place_gcrs_m(lat, lon, when)
    R_itrs = R_itrs_from_gcrs(parse_epoch_utc(EPOCH_UTC))[0]
    # Render frame = GCRS: the Earth's centre from the target, its fixed frame the ITRS.
    earth = earth_body(
        -target_gcrs, R_itrs.T, 0.3, np.array([1.0, 0.0, 0.0]), 1000.0, albedo_map=clear_sky_map
    )
    down = -target_gcrs / np.linalg.norm(target_gcrs)
    hit, _, _, hit_lat, hit_lon = earth.hit(np.zeros(3), down[None, :])
    assert hit[0]
    # The place the ray meets is the one asked for, to the oracle's 0.5 deg.
    assert math.degrees(hit_lat[0]) == pytest.approx(lat, abs=0.5)
    lon_error = (math.degrees(hit_lon[0]) - lon + 180.0) % 360.0 - 180.0
    assert abs(lon_error) < 0.5
    albedo = earth.albedo_at(hit_lat, hit_lon)[0]
    np.testing.assert_allclose(albedo, expected, atol=1e-4)  # 16-bit map cache: 1.5e-5
