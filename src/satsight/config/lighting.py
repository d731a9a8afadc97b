"""Scenario keys of the light: the Sun (direction in the body frame, spectrum, band,
distance), and the Earth and the Moon seen from the target.

With views in the body frame these place the bodies by hand; with frames planned from
orbits only the Sun's spectrum and band and the bodies' surfaces apply (their places come
from the ephemeris). Non-SI units appear only in the key's name (``azimuth_deg``,
``altitude_km``, ``distance_au``).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from satsight.constants import DEFAULT_BAND_NM, EARTH_MEAN_RADIUS_M
from satsight.lighting.light_field import SunLight
from satsight.lighting.solar_spectrum import SPECTRA, band_irradiance_w_m2
from satsight.poses.views import direction_from_angles


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    return direction_from_angles(math.radians(azimuth_deg), math.radians(elevation_deg))


class SunConfig(_Strict):
    """Sun direction (from the target) in the body frame, and its in-band irradiance.

    The irradiance is the solar spectrum integrated over ``band_nm`` at ``distance_au``
    unless ``irradiance_w_m2`` gives it directly.
    """

    azimuth_deg: float = 45.0
    elevation_deg: float = Field(default=30.0, ge=-90, le=90)
    spectrum: Literal[SPECTRA] = "astm_e490"
    band_nm: tuple[float, float] = DEFAULT_BAND_NM
    distance_au: float = Field(default=1.0, gt=0)
    irradiance_w_m2: float | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _band_order(self) -> SunConfig:
        lo, hi = self.band_nm
        if not (0 < lo < hi):
            raise ValueError(f"band_nm must be [lo, hi] with 0 < lo < hi, got {list(self.band_nm)}")
        return self

    @property
    def in_band_irradiance_w_m2(self) -> float:
        if self.irradiance_w_m2 is not None:
            return self.irradiance_w_m2
        return band_irradiance_w_m2(self.band_nm, self.spectrum, self.distance_au)

    def build(self) -> SunLight:
        return SunLight(
            _direction(self.azimuth_deg, self.elevation_deg), self.in_band_irradiance_w_m2
        )


class EarthConfig(_Strict):
    """The Earth seen from the target: direction of its centre (body frame), altitude of
    the target above the mean sphere, and a Lambertian albedo (scalar or per channel; the
    SH light field's, and the body's with ``surface: uniform``), its surface (albedo map or
    uniform) and shape as a body in the scene.

    ``shape: sphere`` is the mean sphere, radius R1 = ``EARTH_MEAN_RADIUS_M`` (6 371 008.8
    m), the sphere ``altitude_km`` is measured from: the target is exactly ``altitude_km``
    above the drawn and lit surface. ``shape: wgs84`` is the ellipsoid (a = 6 378 137 m,
    b = 6 356 752 m), centred at the same point, so its surface below the target lies
    between 7.1 km above and 14.3 km below the mean sphere."""

    azimuth_deg: float = 0.0
    elevation_deg: float = Field(default=-90.0, ge=-90, le=90)
    altitude_km: float = Field(default=500.0, gt=0, le=1e6)
    albedo: float | tuple[float, float, float] = 0.30
    # The Earth as a body in the scene (satsight.lighting.scene_bodies / earth_surface):
    # "map" = land, ocean, ice and seeded clouds (mean 0.30); "uniform" = ``albedo``.
    surface: Literal["map", "uniform"] = "map"
    shape: Literal["wgs84", "sphere"] = "wgs84"
    cloud_fraction: float = Field(default=0.67, ge=0.0, le=1.0)
    cloud_seed: int = Field(default=0, ge=0)

    def albedo_map(self):
        """The surface albedo map, or None for a uniform Earth."""
        if self.surface == "uniform":
            return None
        from satsight.lighting.earth_surface import EarthSurfaceModel, earth_albedo_map

        return earth_albedo_map(
            EarthSurfaceModel(cloud_fraction=self.cloud_fraction, cloud_seed=self.cloud_seed)
        )

    def center_from_target_m(self) -> np.ndarray:
        distance_m = EARTH_MEAN_RADIUS_M + self.altitude_km * 1e3
        return distance_m * _direction(self.azimuth_deg, self.elevation_deg)


class MoonConfig(_Strict):
    """The Moon seen from the target: direction of its centre (body frame), distance, albedo."""

    azimuth_deg: float = 0.0
    elevation_deg: float = Field(default=0.0, ge=-90, le=90)
    distance_km: float = Field(default=384_400.0, gt=2000)
    albedo: float | tuple[float, float, float] = 0.12

    def center_from_target_m(self) -> np.ndarray:
        return self.distance_km * 1e3 * _direction(self.azimuth_deg, self.elevation_deg)
