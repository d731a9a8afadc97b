"""The limiting magnitude of a camera: the faintest star (V) that reaches a given SNR in an
aperture of the pixels that maximise it, with the detector's noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import check_band_nm
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.optics import Optics
from satsight.sensor.star_field import (
    DEFAULT_BAND_NM,
    DEFAULT_STAMP_RADIUS_PX,
    check_exposure_time_s,
    collecting_area_m2,
)
from satsight.sensor.star_photometry import star_photon_flux_m2_s
from satsight.sensor.star_stamps import psf_stamps


@dataclass(frozen=True)
class LimitingMagnitude:
    """The faintest star reaching a target SNR, and the aperture that measures it.

    v_mag: its V magnitude. photons: its mean photons reaching the detector.
    signal_e: mean photo-electrons inside the aperture. n_pixels: aperture size (px).
    aperture: (S, S) bool, the aperture's pixels within a stamp centred on the star.
    fraction: (S, S) float, the star's photon fraction per pixel (the PSF stamp).
    noise_var_per_pixel_e2: read^2 + dark t + g^2 / 12 (e^2).
    quantum_efficiency: the detector's electrons per photon for the star's spectrum.
    """

    v_mag: float
    photons: float
    signal_e: float
    n_pixels: int
    aperture: np.ndarray
    fraction: np.ndarray
    noise_var_per_pixel_e2: float
    quantum_efficiency: float


def limiting_magnitude_details(
    optics: Optics,
    detector_params: DetectorParameters,
    exposure_time_s: float,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    snr: float = 5.0,
    temperature_k: float = 5772.0,
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
) -> LimitingMagnitude:
    """The V magnitude at which a star centred on a pixel reaches ``snr``; see
    :func:`limiting_magnitude` for the model."""
    t = check_exposure_time_s(exposure_time_s)
    if t <= 0:
        raise SatsightError(f"exposure_time_s must be > 0 s for a limiting magnitude; got {t}")
    if not (math.isfinite(float(snr)) and snr > 0):
        raise SatsightError(f"snr must be a positive number; got {snr!r}")
    band = check_band_nm(band_nm)
    p = detector_params
    frac = psf_stamps(
        np.zeros(1),
        np.zeros(1),
        np.array([float(temperature_k)]),
        optics,
        p.pixel_pitch_m,
        band,
        stamp_radius_px,
    )[0]
    order = np.argsort(frac, axis=None)[::-1]
    enclosed = np.cumsum(frac.ravel()[order])
    n = np.arange(1, enclosed.size + 1)
    var_px = p.read_noise_e**2 + p.dark_current_e_per_s * t + p.conversion_gain_e_per_dn**2 / 12
    s2 = float(snr) ** 2
    signal = 0.5 * (s2 + np.sqrt(s2 * s2 + 4.0 * s2 * n * var_px))  # x^2 = S^2 (x + n var)
    eta = float(p.star_quantum_efficiency(band, float(temperature_k))[0])
    photons = signal / (eta * enclosed)
    best = int(np.argmin(photons))
    aperture = np.zeros(frac.size, dtype=bool)
    aperture[order[: best + 1]] = True
    flux = photons[best] / (collecting_area_m2(optics) * optics.transmission * t)
    flux0 = star_photon_flux_m2_s(np.zeros(1), np.array([float(temperature_k)]), band)[0]
    return LimitingMagnitude(
        v_mag=float(-2.5 * math.log10(flux / flux0)),
        photons=float(photons[best]),
        signal_e=float(signal[best]),
        n_pixels=best + 1,
        aperture=aperture.reshape(frac.shape),
        fraction=frac,
        noise_var_per_pixel_e2=float(var_px),
        quantum_efficiency=eta,
    )


def limiting_magnitude(
    optics: Optics,
    detector_params: DetectorParameters,
    exposure_time_s: float,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    snr: float = 5.0,
    temperature_k: float = 5772.0,
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
) -> float:
    """Faintest V magnitude a star (blackbody at ``temperature_k``) is detected at ``snr``.

    Aperture photometry over the n pixels that maximise the SNR (the n brightest pixels of
    the star's pixel-integrated PSF, star centred on a pixel; the best case), with the CCD
    equation (Howell, Handbook of CCD Astronomy, 2nd ed., Eq. 4.4; EMVA 1288 R4.0 Sec. 2):
    SNR = x / sqrt(x + n (sigma_read^2 + D t + g^2 / 12)), x = eta F_n N the photo-electrons
    in the aperture, F_n its enclosed fraction, g^2 / 12 the quantisation noise (e^2), eta
    the detector's QE for the star's black body (``DetectorParameters.
    star_quantum_efficiency``: its curve's photon-weighted mean, or its override). For
    each n the quadratic x^2 - S^2 x - S^2 n B = 0 gives x; the smallest N over n wins.
    The sky background is zero (space; stray light ignored), PRNU ignored (< 1 % of a faint
    signal). V follows from N = flux(V) A tau t with :func:`star_photon_flux_m2_s`.
    """
    return limiting_magnitude_details(
        optics, detector_params, exposure_time_s, band_nm, snr, temperature_k, stamp_radius_px
    ).v_mag
