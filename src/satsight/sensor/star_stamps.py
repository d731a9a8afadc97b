"""Star stamps: each star's photons spread over the pixels by the pixel-integrated,
band-averaged PSF of the optics at its exact sub-pixel position (OTF x phase ramp, inverse
FFT), the PSF weighted by the star's own photon spectrum (its temperature on a cached grid).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from satsight.errors import SatsightError
from satsight.lighting.blackbody import planck_shape_per_m5
from satsight.lighting.solar_spectrum import check_band_nm
from satsight.sensor.mtf import band_wavelengths_m, defocus_mtf, diffraction_mtf
from satsight.sensor.optics import Optics
from satsight.sensor.star_field import (
    DEFAULT_STAMP_RADIUS_PX,
    N_PSF_WAVELENGTHS,
    PSF_TEMPERATURE_RATIO,
    StarsInView,
    star_photon_counts,
)
from satsight.sensor.star_photometry import SOLAR_TEMPERATURE_K


def _oversampling(optics: Optics, pixel_pitch_m: float, band_nm: tuple[float, float]) -> int:
    """Odd s with s / (2 p) above the diffraction cut-off 1 / (lambda_min N)."""
    cutoff = 1.0 / (band_nm[0] * 1e-9 * optics.f_number)
    return 2 * math.ceil(cutoff * pixel_pitch_m) + 1


def psf_temperature_k(temperature_k: np.ndarray) -> np.ndarray:
    """Temperature (K) whose photon spectrum weights a star's PSF: the star's, rounded to a
    geometric grid through 5772 K with ratio 1.25 (so PSFs are computed once per grid value
    and cached; the PSF changes by < 0.3 % of its peak across one grid step)."""
    t = np.asarray(temperature_k, dtype=np.float64)
    step = math.log(PSF_TEMPERATURE_RATIO)
    return SOLAR_TEMPERATURE_K * np.exp(np.rint(np.log(t / SOLAR_TEMPERATURE_K) / step) * step)


@functools.lru_cache(maxsize=64)
def _weighted_otf(
    optics: Optics,
    pixel_pitch_m: float,
    band_nm: tuple[float, float],
    size: int,
    temperature_k: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """System OTF on the fine frequency grid of a size x size stamp, for one spectrum.

    Returns (otf (F, F), rows f_y and columns f_x in FFT order, freq (F,) cycles/m, s) with
    F = size * s: the diffraction OTF averaged over 16 sub-band centre wavelengths weighted
    by the photon spectrum lambda B_lambda(T), times the pixel sinc(p f_x) sinc(p f_y), the
    jitter MTF exp(-2 pi^2 sigma^2 |f|^2) and, with defocus, the signed geometric defocus OTF
    2 J1(pi d |f|) / (pi d |f|) (:func:`satsight.sensor.mtf.defocus_mtf`). The product
    still vanishes beyond the diffraction cut-off, so the grid cuts no frequency.
    """
    s = _oversampling(optics, pixel_pitch_m, band_nm)
    f = np.fft.fftfreq(size * s, d=pixel_pitch_m / s)
    rho = np.hypot(f[:, None], f[None, :])
    lam = band_wavelengths_m(band_nm, N_PSF_WAVELENGTHS)
    weights = lam * planck_shape_per_m5(lam, temperature_k)  # photons: lambda B_lambda
    weights /= weights.sum()
    otf = np.zeros_like(rho)
    for lk, wk in zip(lam, weights, strict=True):
        otf += wk * diffraction_mtf(rho, lk, optics.f_number, optics.obscuration_ratio)
    pix = np.sinc(pixel_pitch_m * f)
    otf *= pix[:, None] * pix[None, :]
    otf *= np.exp(-2.0 * math.pi**2 * optics.jitter_rms_m**2 * rho**2)
    if optics.defocus_blur_diameter_m > 0.0:
        otf *= defocus_mtf(rho, optics.defocus_blur_diameter_m)
    otf.setflags(write=False)
    return otf, f, s


def _fold_and_invert(
    otf: np.ndarray,
    f: np.ndarray,
    s: int,
    size: int,
    dx_px: np.ndarray,
    dy_px: np.ndarray,
    pixel_pitch_m: float,
) -> np.ndarray:
    """(M, size, size) pixel-centre samples of the shifted pixel-integrated PSF."""
    shift = -2j * math.pi * pixel_pitch_m * f
    ex = np.exp(dx_px[:, None] * shift[None, :]).reshape(-1, s, size)
    ey = np.exp(dy_px[:, None] * shift[None, :]).reshape(-1, s, size)
    otf5 = otf.reshape(s, size, s, size)  # [alias y, coarse y, alias x, coarse x]
    half = np.einsum("jakb,mkb->mjab", otf5, ex)
    folded = np.einsum("mjab,mja->mab", half, ey)
    stamps = np.fft.fftshift(np.fft.ifft2(folded).real, axes=(1, 2))
    np.maximum(stamps, 0.0, out=stamps)
    return stamps


def psf_stamps(
    dx_px: np.ndarray,
    dy_px: np.ndarray,
    temperature_k: np.ndarray,
    optics: Optics,
    pixel_pitch_m: float,
    band_nm: tuple[float, float],
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
) -> np.ndarray:
    """(M, S, S) fraction of each star's photons in each pixel, S = 2 R + 1, float64.

    dx_px, dy_px: (M,) offset of the star from the centre pixel of its stamp (px, in
    [-0.5, 0.5]). temperature_k: (M,) the diffraction OTF is averaged over the band's
    sub-band wavelengths weighted by the photon spectrum lambda B_lambda(T) at
    :func:`psf_temperature_k` (flat quantum efficiency).

    Method (exact up to the periodic wrap below): the pixel-integrated PSF sampled at pixel
    centres is the inverse Fourier transform of OTF(f) sinc(p f_x) sinc(p f_y) e^{-2 pi i f.x0}
    (Goodman, Introduction to Fourier Optics, Sec. 6.3; Holst, Ch. 10), OTF = mean
    diffraction OTF x jitter MTF x geometric defocus OTF (signed; 1 without defocus). It is
    evaluated on the frequency grid of an S*s-point stamp with s odd and s / (2 p) above the
    diffraction cut-off (so no frequency is cut),
    multiplied by the sub-pixel phase ramp, folded onto the S x S grid (= sampling at the
    pixel centres, aliases included: the PSF is undersampled) and inverse-FFT'd. Sampling a
    period of S pixels wraps the PSF wings beyond the stamp back into it (at the opposite
    edge): each stamp sums to exactly 1 (the pixel sinc vanishes at every alias of f = 0), so
    a star's photons are conserved; the price is that the outer stamp pixels also hold the
    wings' aliases, about 2 lambda N / (pi^2 R p) of the photons in all (~1 % for R = 8 px at
    f/10 with 15 um pixels), and a centroid bias below ~0.01 px from the wrap.
    """
    R = int(stamp_radius_px)
    if R != stamp_radius_px or R < 1:
        raise SatsightError(f"stamp_radius_px must be a whole number >= 1; got {stamp_radius_px}")
    size = 2 * R + 1
    dx = np.atleast_1d(np.asarray(dx_px, dtype=np.float64))
    dy = np.atleast_1d(np.asarray(dy_px, dtype=np.float64))
    t_psf = psf_temperature_k(np.atleast_1d(np.asarray(temperature_k, dtype=np.float64)))
    band = (float(band_nm[0]), float(band_nm[1]))
    stamps = np.empty((dx.size, size, size))
    for t in np.unique(t_psf):
        sel = t_psf == t
        otf, f, s = _weighted_otf(optics, float(pixel_pitch_m), band, size, float(t))
        stamps[sel] = _fold_and_invert(otf, f, s, size, dx[sel], dy[sel], float(pixel_pitch_m))
    return stamps


def star_photons_image(
    stars: StarsInView,
    shape_hw: tuple[int, int],
    optics: Optics,
    pixel_pitch_m: float,
    exposure_time_s: float,
    band_nm: tuple[float, float],
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
    out: np.ndarray | None = None,
    scale: float | np.ndarray = 1.0,
) -> np.ndarray:
    """(H, W) float32 mean photons per pixel reaching the detector from the stars.

    With ``out`` ((H, W) float32), the stars' photons times ``scale`` are added into it in
    place and it is returned (e.g. scale = photon energy / (pixel area x t) adds them as
    focal-plane irradiance without a full-frame temporary). ``scale`` is one number or
    (M,), one per star (e.g. times each star's quantum efficiency over the detector's).

    Each star delivers N = photon_flux_m2_s x pi D^2 / 4 (1 - eps^2) x tau x t photons,
    spread over a (2 R + 1)^2 stamp by :func:`psf_stamps` (pixel-integrated, photon-weighted
    band-averaged PSF at the star's sub-pixel position; a stamp sums to 1, see there).
    Stamp pixels outside the frame are dropped (those photons miss the detector).
    band_nm must be the band of ``stars`` (their photon flux).
    """
    band = check_band_nm(band_nm)
    if tuple(stars.band_nm) != band:
        raise SatsightError(
            f"band_nm {band} differs from the band of the stars' photon flux {stars.band_nm}; "
            "use the same band for stars_in_view and star_photons_image"
        )
    try:
        h, w = (int(v) for v in shape_hw)
    except (TypeError, ValueError):
        h = w = 0
    if h < 1 or w < 1 or tuple(shape_hw) != (h, w):
        raise SatsightError(f"shape_hw must be (H, W) whole numbers >= 1; got {shape_hw!r}")
    pitch = float(pixel_pitch_m)
    if not (math.isfinite(pitch) and pitch > 0):
        raise SatsightError(f"pixel_pitch_m must be > 0 m; got {pixel_pitch_m!r}")
    counts = star_photon_counts(stars.photon_flux_m2_s, optics, exposure_time_s)
    if out is None:
        image = np.zeros((h, w), dtype=np.float32)
    else:
        image = out
        if image.shape != (h, w) or image.dtype != np.float32:
            raise SatsightError(
                f"out must be a float32 (H, W) = {(h, w)} image; got {image.dtype} {image.shape}"
            )
    factor = np.asarray(scale, dtype=np.float64)
    if factor.shape not in ((), (len(stars),)) or not np.all(np.isfinite(factor) & (factor >= 0)):
        raise SatsightError(
            f"scale must be a finite number >= 0, or ({len(stars)},) of them, one per star; "
            f"got {scale!r}"
        )
    counts = counts * factor
    R = int(stamp_radius_px)
    cx = np.rint(stars.x_px).astype(np.int64)
    cy = np.rint(stars.y_px).astype(np.int64)
    touch = (cx + R >= 0) & (cx - R < w) & (cy + R >= 0) & (cy - R < h) & (counts > 0)
    k = np.flatnonzero(touch)
    if k.size == 0:
        return image
    stamps = psf_stamps(
        stars.x_px[k] - cx[k],
        stars.y_px[k] - cy[k],
        stars.temperature_k[k],
        optics,
        pitch,
        band,
        R,
    )
    for n, j in enumerate(k):
        y0, x0 = cy[j] - R, cx[j] - R
        ya, xa = max(y0, 0), max(x0, 0)
        yb, xb = min(y0 + 2 * R + 1, h), min(x0 + 2 * R + 1, w)
        image[ya:yb, xa:xb] += counts[j] * stamps[n, ya - y0 : yb - y0, xa - x0 : xb - x0]
    return image
