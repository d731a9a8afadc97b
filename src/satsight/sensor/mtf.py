"""MTF and OTF components of the camera: diffraction, pixel, jitter, defocus, their product.

Spatial frequencies are in the focal plane, in cycles per metre (``_cyc_per_m``); one cycle
per millimetre is 1e3 cycles per metre.

Physics and sources:

* Diffraction MTF of a circular pupil: Goodman, "Introduction to Fourier Optics", 3rd ed.,
  Sec. 6.4; annular (centrally obscured) pupil: O'Neill, JOSA 46, 285 (1956), and Mahajan,
  "Optical Imaging and Aberrations, Part II", Sec. 2.4. Here the annular OTF is the exact
  overlap area of two shifted annuli, built from circle-circle intersection areas.
* Pixel MTF |sinc(p f)| for a 100 % fill factor, and jitter MTF exp(-2 pi^2 sigma^2 f^2) for a
  Gaussian random jitter of per-axis RMS sigma: Holst, "Electro-Optical Imaging System
  Performance", 5th ed., Ch. 10 and 11.
* Defocus, geometrical optics: a focal-plane shift dz spreads a point into a uniform disc of
  diameter d = dz / N, whose OTF is 2 J1(pi d f) / (pi d f) (the Fourier transform of the
  pillbox; Holst, Ch. 10, optics MTF; Smith, "Modern Optical Engineering", 4th ed., Ch. 11).
  It is the large-defocus limit of Hopkins' diffraction defocus OTF (Proc. R. Soc. A 231, 91
  (1955)): valid when the peak defocus wavefront error W020 = d / (8 N) exceeds about one
  wave, i.e. d > ~8 lambda N; for smaller d it overstates the loss at high frequencies. Here
  it multiplies the diffraction OTF, which is the usual cascade approximation.
* The response of the renderer's sub-pixel sampling (:func:`render_sampling_otf`): the
  Fourier transform of the average of point samples at the sub-pixel positions (Pharr,
  Jakob & Humphreys, "Physically Based Rendering", 3rd ed., Sec. 7.1, sampling theory).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.special import j1

from satsight.constants import DEFAULT_BAND_NM
from satsight.errors import SatsightError
from satsight.sensor.optics import (
    Optics,
    _check_blur_diameter,
    _check_nonnegative,
    _check_obscuration,
    _check_positive,
)

DEFAULT_N_WAVELENGTHS = 16
"""Number of equal sub-bands whose centre wavelengths sample the band for polychromatic MTF/PSF."""


def _frequencies(freq_cyc_per_m: float | np.ndarray) -> np.ndarray:
    f = np.abs(np.asarray(freq_cyc_per_m, dtype=np.float64))
    if not np.all(np.isfinite(f)):
        raise SatsightError(
            "spatial frequencies must be finite numbers in cycles per metre; got NaN or inf. "
            "Check the frequency grid."
        )
    return f


def _circle_overlap_area(r1: float, r2: float, d: np.ndarray) -> np.ndarray:
    """Area of intersection of two circles of radii r1, r2 whose centres are d apart."""
    d = np.asarray(d, dtype=np.float64)
    if r1 == 0.0 or r2 == 0.0:
        return np.zeros_like(d)
    small = min(r1, r2)
    contained = d <= abs(r1 - r2)
    disjoint = d >= r1 + r2
    partial = ~(contained | disjoint)
    ds = np.where(partial, d, 0.5 * (abs(r1 - r2) + r1 + r2))  # safe value off the lens range
    c1 = np.clip((ds * ds + r1 * r1 - r2 * r2) / (2.0 * ds * r1), -1.0, 1.0)
    c2 = np.clip((ds * ds + r2 * r2 - r1 * r1) / (2.0 * ds * r2), -1.0, 1.0)
    kite = (-ds + r1 + r2) * (ds + r1 - r2) * (ds - r1 + r2) * (ds + r1 + r2)
    lens = r1 * r1 * np.arccos(c1) + r2 * r2 * np.arccos(c2) - 0.5 * np.sqrt(np.maximum(kite, 0))
    return np.where(contained, math.pi * small * small, np.where(partial, lens, 0.0))


def diffraction_mtf(
    freq_cyc_per_m: float | np.ndarray,
    wavelength_m: float,
    f_number: float,
    obscuration_ratio: float = 0.0,
) -> np.ndarray:
    """Incoherent diffraction MTF of an aberration-free circular or annular pupil.

    freq_cyc_per_m: focal-plane spatial frequency (cycles/m), any shape; the sign is ignored.
    The cut-off is f_c = 1 / (lambda N) = D / (lambda f). With x = f / f_c, the clear pupil
    gives (2/pi)(arccos x - x sqrt(1 - x^2)) (Goodman, Sec. 6.4). For an obscuration ratio
    eps > 0 the OTF is the overlap area of the annulus {eps <= r <= 1} with a copy shifted by
    2x, over the annulus area pi(1 - eps^2) (O'Neill 1956; Mahajan Part II, Sec. 2.4), computed
    exactly from circle-circle intersection areas. Returns float64 in [0, 1], shaped like freq.
    """
    lam = _check_positive("wavelength_m", wavelength_m, "m")
    n = _check_positive("f_number", f_number, "(dimensionless)")
    eps = _check_obscuration(obscuration_ratio)
    x = _frequencies(freq_cyc_per_m) * lam * n
    xc = np.minimum(x, 1.0)
    if eps == 0.0:
        mtf = (2.0 / math.pi) * (np.arccos(xc) - xc * np.sqrt(1.0 - xc * xc))
    else:
        d = 2.0 * x  # shift of the pupil copies, in units of the pupil radius
        overlap = (
            _circle_overlap_area(1.0, 1.0, d)
            - 2.0 * _circle_overlap_area(1.0, eps, d)
            + _circle_overlap_area(eps, eps, d)
        )
        mtf = overlap / (math.pi * (1.0 - eps * eps))
    return np.where(x >= 1.0, 0.0, np.clip(mtf, 0.0, 1.0))


def pixel_mtf(freq_cyc_per_m: float | np.ndarray, pixel_pitch_m: float) -> np.ndarray:
    """Pixel-aperture MTF |sinc(p f)| = |sin(pi p f) / (pi p f)| (Holst, Ch. 10).

    Assumes a square pixel of side p = pixel_pitch_m (m) with 100 % fill factor and uniform
    response. Zeros at f = k / p. Returns float64 shaped like freq.
    """
    p = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    return np.abs(np.sinc(p * _frequencies(freq_cyc_per_m)))


def jitter_mtf(
    freq_cyc_per_m: float | np.ndarray, jitter_rms_rad: float, focal_length_m: float
) -> np.ndarray:
    """MTF of random Gaussian line-of-sight jitter, exp(-2 pi^2 sigma^2 f^2) (Holst, Ch. 11).

    sigma = jitter_rms_rad * focal_length_m is the per-axis RMS image motion in the focal plane
    (m); the MTF falls to exp(-1/2) at f = 1 / (2 pi sigma). Returns float64 shaped like freq.
    """
    jitter = _check_nonnegative("jitter_rms_rad", jitter_rms_rad, "rad")
    sigma = jitter * _check_positive("focal_length_m", focal_length_m, "m")
    f = _frequencies(freq_cyc_per_m)
    return np.exp(-2.0 * math.pi**2 * sigma * sigma * f * f)


def _jinc(x: np.ndarray) -> np.ndarray:
    """2 J1(x) / x, with its limit 1 at x = 0 (x >= 0, float64)."""
    nz = x > 1e-8
    xs = np.where(nz, x, 1.0)
    return np.where(nz, 2.0 * j1(xs) / xs, 1.0)


def defocus_mtf(freq_cyc_per_m: float | np.ndarray, blur_diameter_m: float) -> np.ndarray:
    """Geometric defocus OTF of a uniform blur disc, 2 J1(pi d f) / (pi d f) (dimensionless).

    freq_cyc_per_m: focal-plane spatial frequency (cycles/m), any shape; the sign is ignored.
    blur_diameter_m: diameter d (m) of the blur circle, d = dz / N for a focal-plane shift dz
    at f-number N. The PSF is a pillbox of diameter d (geometrical optics), whose Fourier
    transform is this jinc (Holst, "Electro-Optical Imaging System Performance", Ch. 10;
    Smith, "Modern Optical Engineering", 4th ed., Ch. 11). It is the geometric approximation,
    valid when the defocus wavefront error W020 = d / (8 N) is more than about one wave
    (d >> lambda N); near focus the diffraction defocus OTF (Hopkins 1955) applies instead.

    The result is the OTF, real and signed: it is 1 at f = 0 and everywhere for d = 0, first
    zero at f = 3.8317 / (pi d), then negative lobes (contrast reversal, down to -0.132) and
    decaying oscillations. The MTF is its absolute value; the sign is kept here because the
    OTF is what multiplies into a PSF. Returns float64 shaped like freq.
    """
    d = _check_blur_diameter(blur_diameter_m, "blur_diameter_m")
    f = _frequencies(freq_cyc_per_m)
    if d == 0.0:
        return np.ones_like(f)
    return _jinc(math.pi * d * f)


def band_wavelengths_m(
    band_nm: tuple[float, float] | None = None, n: int = DEFAULT_N_WAVELENGTHS
) -> np.ndarray:
    """Centre wavelengths (m), shape (n,), of n equal sub-bands of band_nm = (lo, hi) in nm.

    Defaults to the project's band (``satsight.constants.DEFAULT_BAND_NM``).
    """
    if band_nm is None:
        band_nm = DEFAULT_BAND_NM
    lo, hi = (float(b) for b in band_nm)
    if not (0 < lo < hi and math.isfinite(hi)):
        raise SatsightError(f"band_nm must be (low, high) with 0 < low < high nm; got {band_nm}")
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise SatsightError(f"the number of wavelengths must be a positive integer; got {n!r}")
    edges = np.linspace(lo, hi, int(n) + 1)
    return 0.5 * (edges[:-1] + edges[1:]) * 1e-9


def _spectral_weights(wavelengths_m: Sequence[float] | np.ndarray, weights) -> tuple:
    lam = np.atleast_1d(np.asarray(wavelengths_m, dtype=np.float64))
    if lam.ndim != 1 or lam.size == 0 or not np.all((lam > 0) & np.isfinite(lam)):
        raise SatsightError(
            "wavelengths_m must be a non-empty 1-D list of positive wavelengths in metres; "
            f"got {wavelengths_m!r}. 550 nm is 550e-9 m."
        )
    if weights is None:
        w = np.full(lam.shape, 1.0 / lam.size)
    else:
        w = np.atleast_1d(np.asarray(weights, dtype=np.float64))
        if w.shape != lam.shape or not np.all((w >= 0) & np.isfinite(w)) or w.sum() <= 0:
            raise SatsightError(
                f"weights must be {lam.size} non-negative numbers (one per wavelength), not all "
                f"zero; got {weights!r}"
            )
        w = w / w.sum()
    return lam, w


def system_mtf(
    freq_cyc_per_m: float | np.ndarray,
    optics: Optics,
    pixel_pitch_m: float,
    wavelengths_m: Sequence[float] | np.ndarray | None = None,
    weights: Sequence[float] | np.ndarray | None = None,
) -> np.ndarray:
    """System MTF: band-averaged diffraction x pixel x jitter x defocus (dimensionless).

    The diffraction MTF is averaged over ``wavelengths_m`` with ``weights`` (normalised to sum
    to 1; uniform if None). The default wavelengths are the centres of 16 equal sub-bands of
    the default band (450-900 nm), i.e. a flat spectrum in the detected signal, a stand-in for
    the true (solar x reflectance x QE) weighting. With defocus (optics.defocus_blur_diameter_m
    > 0) the product includes the signed geometric defocus OTF (:func:`defocus_mtf`), so the
    result is the real system OTF and may be negative beyond the defocus' first zero; its
    absolute value is the MTF. Returns float64 shaped like freq.
    """
    if wavelengths_m is None:
        wavelengths_m = band_wavelengths_m()
    lam, w = _spectral_weights(wavelengths_m, weights)
    f = _frequencies(freq_cyc_per_m)
    diff = sum(
        wk * diffraction_mtf(f, lk, optics.f_number, optics.obscuration_ratio)
        for lk, wk in zip(lam, w, strict=True)
    )
    mtf = (
        diff
        * pixel_mtf(f, pixel_pitch_m)
        * jitter_mtf(f, optics.jitter_rms_rad, optics.focal_length_m)
    )
    if optics.defocus_blur_diameter_m > 0.0:
        mtf = mtf * defocus_mtf(f, optics.defocus_blur_diameter_m)
    return mtf


def system_otf_2d(
    fx_cyc_per_m: float | np.ndarray,
    fy_cyc_per_m: float | np.ndarray,
    optics: Optics,
    pixel_pitch_m: float,
    wavelengths_m: Sequence[float] | np.ndarray | None = None,
    weights: Sequence[float] | np.ndarray | None = None,
) -> np.ndarray:
    """Two-dimensional system OTF H(fx, fy) of optics and pixel (dimensionless, real).

    fx_cyc_per_m, fy_cyc_per_m: focal-plane frequencies along the detector rows and columns
    (cycles/m), broadcast together. H is the band-averaged diffraction OTF of the (annular)
    pupil at the radial frequency rho = sqrt(fx^2 + fy^2), times the square pixel's aperture
    sinc(p fx) sinc(p fy) (signed), the jitter MTF exp(-2 pi^2 sigma^2 rho^2) and, with
    defocus, the signed geometric defocus OTF at rho: the same factors as
    :func:`system_mtf` (and the same default wavelengths and weights), which it equals along
    either axis (fy = 0 or fx = 0) wherever the pixel sinc is positive, |f| < 1 / p. All
    factors are real and even, so H is real and even in fx and in fy. Returns float64 of the
    broadcast shape.
    """
    if wavelengths_m is None:
        wavelengths_m = band_wavelengths_m()
    lam, w = _spectral_weights(wavelengths_m, weights)
    p = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    fx, fy = np.broadcast_arrays(_frequencies(fx_cyc_per_m), _frequencies(fy_cyc_per_m))
    rho = np.hypot(fx, fy)
    otf = sum(
        wk * diffraction_mtf(rho, lk, optics.f_number, optics.obscuration_ratio)
        for lk, wk in zip(lam, w, strict=True)
    )
    otf = otf * np.sinc(p * fx) * np.sinc(p * fy)
    otf = otf * jitter_mtf(rho, optics.jitter_rms_rad, optics.focal_length_m)
    if optics.defocus_blur_diameter_m > 0.0:
        otf = otf * defocus_mtf(rho, optics.defocus_blur_diameter_m)
    return otf


def check_render_sampling(supersampling: int, samples_per_pixel: int) -> tuple[int, int]:
    """The renderer's sub-pixel sampling (s, spp) as whole numbers >= 1, or a teaching error."""
    for name, value in (("supersampling", supersampling), ("samples_per_pixel", samples_per_pixel)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise SatsightError(
                f"{name} must be a whole number >= 1 (the render settings' value); got {value!r}"
            )
    return int(supersampling), int(samples_per_pixel)


def render_sampling_otf(
    freq_cyc_per_m: float | np.ndarray,
    pixel_pitch_m: float,
    supersampling: int = 1,
    samples_per_pixel: int = 1,
) -> np.ndarray:
    """Expected response S(f) of the renderer's sub-pixel sampling along one pixel axis.

    A rendered pixel is the mean of point samples of the radiance at sub-pixel positions
    (``satsight.render.camera_rays``): with samples_per_pixel = 1, the centres of the s x s
    strata (s = supersampling), offsets (j + 1/2 - s/2) p / s per axis; with
    samples_per_pixel > 1, positions spread uniformly over each stratum (a Kronecker
    sequence with a uniform random shift per pixel), which together cover the pixel
    uniformly. The pixel value's expected transfer function is the Fourier transform of the
    average of those samples (Pharr, Jakob & Humphreys, "Physically Based Rendering", 3rd
    ed., Sec. 7.1), a separable product of this function along each axis:

    * stratum centres: (1 / s) sum_j cos(2 pi f p (j + 1/2 - s/2) / s)
      = sin(pi f p) / (s sin(pi f p / s)) (the Dirichlet kernel; 1 for s = 1);
    * uniformly spread positions: sinc(f p), the pixel box (in expectation; each frame's
      deviation from it is sampling noise).

    Over |f| <= 1 / (2 p) (the pixel Nyquist frequency) S lies in [2 / pi, 1]. Returns
    float64 shaped like freq (signed: the sign of f does not matter).
    """
    s, spp = check_render_sampling(supersampling, samples_per_pixel)
    p = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    u = p * _frequencies(freq_cyc_per_m)  # cycles per pixel
    if spp > 1:
        return np.sinc(u)
    if s == 1:
        return np.ones_like(u)
    offsets = (np.arange(s) + 0.5 - 0.5 * s) / s
    return np.mean(np.cos(2.0 * math.pi * u[..., None] * offsets), axis=-1)
