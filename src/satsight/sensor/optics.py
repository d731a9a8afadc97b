"""Telescope optics: the entrance pupil, focal length and transmission, and the camera equation.

The optics sit between the radiance image (what a pinhole camera sees, W m^-2 sr^-1) and
the detector. This module holds the telescope's description (:class:`Optics`) and the
focal-plane irradiance of an extended source; the blur is in the modules beside it:
``satsight.sensor.mtf`` (MTF / OTF components), ``satsight.sensor.psf`` (kernels),
``satsight.sensor.convolution`` (applying a kernel to an image) and
``satsight.sensor.mtf_plot``.

Assumptions (the paper gives no aperture and no transmission):

* ``DEFAULT_APERTURE_DIAMETER_M``: 0.3 m for the high-resolution mode (f = 3 m, so f/10) and
  0.1 m for the wide-field mode (f = 0.7 m, so f/7). These are plausible refractor /
  Cassegrain sizes for such focal lengths, not values from the paper.
* ``DEFAULT_TRANSMISSION`` = 0.8: band-averaged transmission of the optics (mirror or lens
  losses and filters), an assumption.
* No central obscuration, no jitter, no defocus, no aberrations by default: a
  diffraction-limited, unobscured, perfectly focused and stable telescope.

Camera equation (extended source, on axis): E = pi L tau (1 - eps^2) / (4 N^2), Slater,
"Remote Sensing: Optics and Optical Systems" (1980), Ch. 7, and Holst, "Electro-Optical
Imaging System Performance", 5th ed., Ch. 12. It is the paraxial, large-N form (the exact
aplanatic form is pi L tau sin^2(theta') with sin theta' = 1 / (2 N), the same to 1 / (4 N^2)
relative); off axis the irradiance falls as cos^4 of the field angle (natural vignetting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError

DEFAULT_TRANSMISSION = 0.8
"""Band-averaged optical transmission (assumption; the paper gives none)."""

DEFAULT_APERTURE_DIAMETER_M = {"high_resolution": 0.3, "wide_field": 0.1}
"""Entrance-pupil diameters per camera preset (assumptions: f/10 at f = 3 m, f/7 at 0.7 m)."""


def _check_positive(name: str, value: float, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SatsightError(f"{name} must be a positive number in {unit}; got {value!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise SatsightError(
            f"{name} must be a positive, finite number in {unit}; got {value!r}. "
            "Pass a value in SI units (metres, radians)."
        )
    return v


def _check_nonnegative(name: str, value: float, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SatsightError(f"{name} must be a number >= 0 in {unit}; got {value!r}") from None
    if not (v >= 0 and math.isfinite(v)):
        raise SatsightError(f"{name} must be a finite number >= 0 in {unit}; got {value!r}")
    return v


def _check_obscuration(value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (0.0 <= v < 1.0):
        raise SatsightError(
            "obscuration_ratio (central obscuration diameter / aperture diameter) must be in "
            f"[0, 1); got {value!r}. Use 0 for an unobscured pupil."
        )
    return v


def _check_blur_diameter(value: float, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (v >= 0 and math.isfinite(v)):
        raise SatsightError(
            f"{name} (the geometric defocus blur-circle diameter) must be a finite number >= 0 "
            f"in metres; got {value!r}. A focal-plane shift dz at f-number N gives d = dz / N; "
            "use 0 for a focused telescope."
        )
    return v


@dataclass(frozen=True)
class Optics:
    """A telescope described by its entrance pupil and effective focal length.

    aperture_diameter_m: entrance-pupil diameter D (m). focal_length_m: effective focal length
    f (m), the same as the pinhole camera's. transmission: band-averaged transmission tau in
    (0, 1] (default 0.8, an assumption). obscuration_ratio: central-obscuration diameter over
    D, eps in [0, 1). jitter_rms_rad: per-axis RMS line-of-sight jitter during the exposure
    (rad), modelled as a Gaussian blur. defocus_blur_diameter_m: diameter d (m) of the
    geometric blur circle in the focal plane from a focus error; a focal-plane shift dz gives
    d = dz / N (see :func:`defocus_mtf`).
    """

    aperture_diameter_m: float
    focal_length_m: float
    transmission: float = DEFAULT_TRANSMISSION
    obscuration_ratio: float = 0.0
    jitter_rms_rad: float = 0.0
    defocus_blur_diameter_m: float = 0.0

    def __post_init__(self) -> None:
        _check_positive("aperture_diameter_m", self.aperture_diameter_m, "m")
        _check_positive("focal_length_m", self.focal_length_m, "m")
        tau = _check_positive("transmission", self.transmission, "(fraction)")
        if tau > 1.0:
            raise SatsightError(
                f"transmission must be in (0, 1]; got {self.transmission!r}. "
                "Pass a fraction, not a percentage."
            )
        _check_obscuration(self.obscuration_ratio)
        _check_nonnegative("jitter_rms_rad", self.jitter_rms_rad, "rad")
        _check_blur_diameter(self.defocus_blur_diameter_m, "defocus_blur_diameter_m")
        if self.focal_length_m / self.aperture_diameter_m < 1.0:
            raise SatsightError(
                f"f-number f/D = {self.focal_length_m / self.aperture_diameter_m:.3g} is below 1; "
                "the paraxial camera equation used here needs N >> 1. "
                "Check the aperture and focal length (both in metres)."
            )

    @property
    def f_number(self) -> float:
        """Working f-number N = f / D (dimensionless)."""
        return self.focal_length_m / self.aperture_diameter_m

    @property
    def jitter_rms_m(self) -> float:
        """Per-axis RMS jitter blur in the focal plane, sigma = jitter_rms_rad * f (m)."""
        return self.jitter_rms_rad * self.focal_length_m

    @classmethod
    def for_preset(cls, preset: str, **overrides: float) -> Optics:
        """Default optics for a camera preset ("high_resolution" or "wide_field").

        Focal length from the pinhole preset, aperture from ``DEFAULT_APERTURE_DIAMETER_M``
        (assumption). Keyword overrides replace any field.
        """
        from satsight.camera.pinhole import CAMERA_PRESETS

        if preset not in DEFAULT_APERTURE_DIAMETER_M or preset not in CAMERA_PRESETS:
            raise SatsightError(
                f"unknown camera preset {preset!r}; expected one of "
                f"{sorted(DEFAULT_APERTURE_DIAMETER_M)}"
            )
        fields: dict[str, float] = {
            "aperture_diameter_m": DEFAULT_APERTURE_DIAMETER_M[preset],
            "focal_length_m": CAMERA_PRESETS[preset]().focal_length_m,
        }
        fields.update(overrides)
        return cls(**fields)


# --- focal-plane irradiance ------------------------------------------------------------------


def focal_plane_irradiance_w_m2(
    radiance_w_m2_sr: float | np.ndarray,
    optics: Optics,
    cos4_angle_rad: float | np.ndarray | None = None,
) -> np.ndarray:
    """Focal-plane irradiance (W m^-2) of an extended source of radiance L (W m^-2 sr^-1).

    E = pi L tau (1 - eps^2) / (4 N^2) for a distant object imaged on axis (Slater 1980, Ch. 7;
    Holst, Ch. 12), with (1 - eps^2) the unobscured fraction of the pupil area. This is the
    paraxial, N >> 1 form of E = pi L tau sin^2(theta'). When ``cos4_angle_rad`` (the field
    angle theta of each pixel from the optical axis, rad, broadcastable to the radiance) is
    given, the result is multiplied by cos^4(theta) (natural vignetting).

    Returns an array shaped like the broadcast of the inputs, float64 (float32 in, float32 out).
    """
    radiance = np.asarray(radiance_w_m2_sr)
    if not np.issubdtype(radiance.dtype, np.floating):
        radiance = radiance.astype(np.float64)
    eps = optics.obscuration_ratio
    factor = math.pi * optics.transmission * (1.0 - eps * eps) / (4.0 * optics.f_number**2)
    irradiance = radiance * radiance.dtype.type(factor)
    if cos4_angle_rad is not None:
        theta = np.asarray(cos4_angle_rad, dtype=np.float64)
        if not np.all(np.abs(theta) < math.pi / 2):
            raise SatsightError(
                "cos4_angle_rad must hold field angles from the optical axis in (-pi/2, pi/2) "
                "rad; got values outside. Pass angles in radians."
            )
        irradiance = irradiance * np.cos(theta).astype(radiance.dtype) ** 4
    return irradiance
