"""Scenario keys of the camera's sensor: optics, detector, exposure, and the star field.

Every key has a default (the CCD231-84-class detector and the assumed apertures of
``satsight.sensor``), so a scenario without these sections gets a complete camera.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from satsight.sensor.detector import DetectorParameters
from satsight.sensor.exposure_rule import ExposureRule
from satsight.sensor.optics import DEFAULT_APERTURE_DIAMETER_M, DEFAULT_TRANSMISSION, Optics
from satsight.sensor.star_catalog import MAX_V_MAG_LIMIT

_DETECTOR = DetectorParameters()


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class OpticsConfig(_Strict):
    """The telescope in front of the detector (its focal length is the camera's)."""

    aperture_diameter_m: float | None = Field(default=None, gt=0, le=10)
    transmission: float = Field(default=DEFAULT_TRANSMISSION, gt=0, le=1)
    obscuration_ratio: float = Field(default=0.0, ge=0, lt=1)
    jitter_rms_urad: float = Field(default=0.0, ge=0, le=1e4)
    defocus_blur_um: float = Field(default=0.0, ge=0, le=1e4)
    """Diameter of the geometric defocus blur circle in the focal plane (um); a focal-plane
    shift dz at f-number N gives dz / N. 0 is a focused telescope."""

    def build(self, preset: str, focal_length_m: float) -> Optics:
        """The optics; the aperture defaults to the preset's assumed diameter."""
        aperture = self.aperture_diameter_m or DEFAULT_APERTURE_DIAMETER_M[preset]
        return Optics(
            aperture_diameter_m=aperture,
            focal_length_m=focal_length_m,
            transmission=self.transmission,
            obscuration_ratio=self.obscuration_ratio,
            jitter_rms_rad=self.jitter_rms_urad * 1e-6,
            defocus_blur_diameter_m=self.defocus_blur_um * 1e-6,
        )


class DetectorConfig(_Strict):
    """Detector parameters; defaults describe a CCD231-84-class sensor (see
    ``satsight.sensor.detector.DetectorParameters`` for the source of each)."""

    quantum_efficiency: float | None = Field(default=_DETECTOR.quantum_efficiency, gt=0, le=1)
    """null (default): the CCD231-84 QE curve, photon-weighted over the band by each light's
    spectrum; a number in (0, 1]: that QE for every light."""
    dark_current_e_per_s: float = Field(default=_DETECTOR.dark_current_e_per_s, ge=0)
    read_noise_e: float = Field(default=_DETECTOR.read_noise_e, ge=0)
    full_well_e: float = Field(default=_DETECTOR.full_well_e, gt=0)
    conversion_gain_e_per_dn: float = Field(default=_DETECTOR.conversion_gain_e_per_dn, gt=0)
    bias_dn: float = Field(default=_DETECTOR.bias_dn, ge=0)
    adc_bits: int = Field(default=_DETECTOR.adc_bits, ge=1, le=16)
    prnu_fraction: float = Field(default=_DETECTOR.prnu_fraction, ge=0, le=0.2)
    dsnu_e_per_s: float = Field(default=_DETECTOR.dsnu_e_per_s, ge=0)
    blooming: bool = _DETECTOR.blooming

    @model_validator(mode="after")
    def _consistent(self) -> DetectorConfig:
        self.build(_DETECTOR.pixel_pitch_m)  # the parameter checks, with their messages
        return self

    def build(self, pixel_pitch_m: float) -> DetectorParameters:
        """The detector, with the camera's pixel pitch."""
        return DetectorParameters(pixel_pitch_m=pixel_pitch_m, **self.model_dump())


_EXPOSURE = ExposureRule()


class ExposureConfig(_Strict):
    """How long each frame integrates (``satsight.sensor.exposure_rule``, which it builds).

    ``mode: auto`` picks, per frame, the time that puts the ``percentile`` of the target's
    focal-plane irradiance at ``fill_fraction`` of full well (a few brighter glints may
    saturate), clipped to [min_time_s, max_time_s]; frames with no lit target use
    ``time_s``. ``mode: fixed`` uses ``time_s`` for every frame.
    """

    mode: Literal["auto", "fixed"] = _EXPOSURE.mode
    time_s: float = Field(default=_EXPOSURE.time_s, gt=0, le=3600)
    fill_fraction: float = Field(default=_EXPOSURE.fill_fraction, gt=0, le=1)
    percentile: float = Field(default=_EXPOSURE.percentile, gt=0, le=100)
    min_time_s: float = Field(default=_EXPOSURE.min_time_s, gt=0)
    max_time_s: float = Field(default=_EXPOSURE.max_time_s, gt=0, le=3600)

    def build(self) -> ExposureRule:
        return ExposureRule(**self.model_dump())

    @model_validator(mode="after")
    def _ordered(self) -> ExposureConfig:
        if self.min_time_s > self.max_time_s:
            raise ValueError(
                f"exposure.min_time_s ({self.min_time_s:g} s) must not exceed max_time_s "
                f"({self.max_time_s:g} s)"
            )
        return self


class StarsConfig(_Strict):
    """The star field behind the target (frames planned from orbits only: it needs the
    camera's inertial attitude and the epoch). The catalogue holds stars to V 9.95."""

    enabled: bool = True
    v_mag_limit: float = Field(default=9.5, ge=-2, le=MAX_V_MAG_LIMIT)
    earth_atmosphere_margin_km: float = Field(default=100.0, ge=0, le=1000)

    @model_validator(mode="after")
    def _finite(self) -> StarsConfig:
        if not math.isfinite(self.v_mag_limit):
            raise ValueError("stars.v_mag_limit must be a finite V magnitude")
        return self
