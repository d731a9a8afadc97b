"""Telescope optics: focal-plane irradiance, MTF components, the polychromatic PSF.

The optics sit between the radiance image (what a pinhole camera sees, W m^-2 sr^-1) and
the detector. Spatial frequencies are in the focal plane, in cycles per metre (``_cyc_per_m``);
one cycle per millimetre is 1e3 cycles per metre.

Assumptions (the paper gives no aperture and no transmission):

* ``DEFAULT_APERTURE_DIAMETER_M``: 0.3 m for the high-resolution mode (f = 3 m, so f/10) and
  0.1 m for the wide-field mode (f = 0.7 m, so f/7). These are plausible refractor /
  Cassegrain sizes for such focal lengths, not values from the paper.
* ``DEFAULT_TRANSMISSION`` = 0.8: band-averaged transmission of the optics (mirror or lens
  losses and filters), an assumption.
* No central obscuration, no jitter, no defocus, no aberrations by default: a
  diffraction-limited, unobscured, perfectly focused and stable telescope.

Physics and sources:

* Camera equation (extended source, on axis): E = pi L tau (1 - eps^2) / (4 N^2), Slater,
  "Remote Sensing: Optics and Optical Systems" (1980), Ch. 7, and Holst, "Electro-Optical
  Imaging System Performance", 5th ed., Ch. 12. It is the paraxial, large-N form (the exact
  aplanatic form is pi L tau sin^2(theta') with sin theta' = 1 / (2 N), the same to 1 / (4 N^2)
  relative); off axis the irradiance falls as cos^4 of the field angle (natural vignetting).
* Diffraction MTF of a circular pupil: Goodman, "Introduction to Fourier Optics", 3rd ed.,
  Sec. 6.4; annular (centrally obscured) pupil: O'Neill, JOSA 46, 285 (1956), and Mahajan,
  "Optical Imaging and Aberrations, Part II", Sec. 2.4. Here the annular OTF is the exact
  overlap area of two shifted annuli, built from circle-circle intersection areas.
* PSF: Airy pattern, Born & Wolf, "Principles of Optics", 7th ed., Sec. 8.5.2 (83.8 % of the
  power inside the first dark ring), and its annular form (Mahajan, Sec. 2.4).
* Pixel MTF |sinc(p f)| for a 100 % fill factor, and jitter MTF exp(-2 pi^2 sigma^2 f^2) for a
  Gaussian random jitter of per-axis RMS sigma: Holst, Ch. 10 and 11.
* Defocus, geometrical optics: a focal-plane shift dz spreads a point into a uniform disc of
  diameter d = dz / N, whose OTF is 2 J1(pi d f) / (pi d f) (the Fourier transform of the
  pillbox; Holst, Ch. 10, optics MTF; Smith, "Modern Optical Engineering", 4th ed., Ch. 11).
  It is the large-defocus limit of Hopkins' diffraction defocus OTF (Proc. R. Soc. A 231, 91
  (1955)): valid when the peak defocus wavefront error W020 = d / (8 N) exceeds about one
  wave, i.e. d > ~8 lambda N; for smaller d it overstates the loss at high frequencies. Here
  it multiplies the diffraction OTF, which is the usual cascade approximation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.fft
from scipy.signal import fftconvolve
from scipy.special import erf, j1

from satsight.errors import SatsightError
from satsight.sensor.threads import check_threads, run_jobs

DEFAULT_TRANSMISSION = 0.8
"""Band-averaged optical transmission (assumption; the paper gives none)."""

DEFAULT_APERTURE_DIAMETER_M = {"high_resolution": 0.3, "wide_field": 0.1}
"""Entrance-pupil diameters per camera preset (assumptions: f/10 at f = 3 m, f/7 at 0.7 m)."""

DEFAULT_N_WAVELENGTHS = 16
"""Number of equal sub-bands whose centre wavelengths sample the band for polychromatic MTF/PSF."""

_FIRST_AIRY_ZERO = 3.8317059702075125  # first zero of J1: first dark ring at v = this

_FFT_BAND_ELEMENTS = 1 << 18
"""Elements per band of the banded FFT convolution (about 256 rows of a 1000-wide window)."""


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


def _frequencies(freq_cyc_per_m: float | np.ndarray) -> np.ndarray:
    f = np.abs(np.asarray(freq_cyc_per_m, dtype=np.float64))
    if not np.all(np.isfinite(f)):
        raise SatsightError(
            "spatial frequencies must be finite numbers in cycles per metre; got NaN or inf. "
            "Check the frequency grid."
        )
    return f


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


# --- MTF components --------------------------------------------------------------------------


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

    Defaults to the project's band (``satsight.lighting.solar_spectrum.DEFAULT_BAND_NM``).
    """
    if band_nm is None:
        from satsight.lighting.solar_spectrum import DEFAULT_BAND_NM

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


# --- PSF -------------------------------------------------------------------------------------


def _annular_airy_intensity(v: np.ndarray, eps: float) -> np.ndarray:
    """Normalised intensity [2J1(v)/v - eps^2 2J1(eps v)/(eps v)]^2 / (1 - eps^2)^2, 1 at v=0."""
    v = np.asarray(v, dtype=np.float64)
    nz = v > 1e-8
    vs = np.where(nz, v, 1.0)
    amp = np.where(nz, 2.0 * j1(vs) / vs, 1.0)
    if eps > 0.0:
        ev = eps * vs
        amp = amp - eps * eps * np.where(nz & (ev > 1e-8), 2.0 * j1(ev) / ev, 1.0)
        amp = amp / (1.0 - eps * eps)
    return amp * amp


def _gaussian_kernel_1d(sigma_samples: float, radius: int) -> np.ndarray:
    """Gaussian of std sigma (in samples) integrated over each unit sample, length 2 r + 1."""
    edges = np.arange(-radius, radius + 2) - 0.5
    cdf = 0.5 * (1.0 + erf(edges / (math.sqrt(2.0) * sigma_samples)))
    k = np.diff(cdf)
    return k / k.sum()


def _disc_quadrant_area(x: np.ndarray, y: np.ndarray, radius: float) -> np.ndarray:
    """Area of the disc x'^2 + y'^2 <= radius^2 inside [0, x] x [0, y], for x, y >= 0.

    G(x, y) = int_0^min(x, R) min(y, h(t)) dt with h(t) = sqrt(R^2 - t^2): y t up to
    t_c = sqrt(R^2 - y^2), then H(t) = (t h(t) + R^2 asin(t / R)) / 2 (the area under the
    circle) beyond it.
    """
    r2 = radius * radius
    xr = np.minimum(x, radius)
    xc = np.sqrt(np.maximum(r2 - y * y, 0.0))

    def under_circle(t: np.ndarray) -> np.ndarray:
        return 0.5 * (t * np.sqrt(np.maximum(r2 - t * t, 0.0)) + r2 * np.arcsin(t / radius))

    return np.where(xr <= xc, y * xr, y * xc + under_circle(xr) - under_circle(np.minimum(xc, xr)))


def _pillbox_kernel(diameter_samples: float, half_width: int) -> np.ndarray:
    """Uniform disc of diameter d (in samples) averaged over each unit sample, (2 h + 1)^2.

    Each value is the exact area of the disc inside that sample, over the disc's area pi d^2 / 4
    (the signed quadrant areas F(x, y) = sgn x sgn y G(|x|, |y|) of the disc, differenced at
    the sample's four corners), so the kernel sums to 1 when h >= d / 2 + 1/2 and loses the
    part of the disc beyond the half-width h otherwise. A disc inside the centre sample
    (d <= 1) gives the unit impulse.
    """
    radius = 0.5 * diameter_samples
    edges = np.arange(-half_width, half_width + 2) - 0.5  # (2 h + 2,) sample edges
    ex, ey = edges[None, :], edges[:, None]
    corner = np.sign(ex) * np.sign(ey) * _disc_quadrant_area(np.abs(ex), np.abs(ey), radius)
    area = corner[1:, 1:] - corner[1:, :-1] - corner[:-1, 1:] + corner[:-1, :-1]
    return np.maximum(area, 0.0) / (math.pi * radius * radius)


def psf_kernel(
    optics: Optics,
    wavelengths_m: Sequence[float] | np.ndarray | float,
    weights: Sequence[float] | np.ndarray | None,
    sample_pitch_m: float,
    size_px: int,
    subsamples: int = 5,
) -> np.ndarray:
    """Polychromatic PSF kernel (size_px, size_px), float64, summing to 1.

    Each sample of pitch ``sample_pitch_m`` (m; the supersampled grid, pixel pitch / s) holds
    the fraction of the image power that falls on it. The monochromatic diffraction PSF of the
    (annular) pupil is I(v) ∝ [2J1(v)/v - eps^2 2J1(eps v)/(eps v)]^2, v = pi r / (lambda N)
    (Born & Wolf Sec. 8.5.2; Mahajan Part II Sec. 2.4); it is averaged over each sample with
    a subsamples x subsamples midpoint rule, normalised per wavelength to sum 1 on the kernel
    (the power in the wings beyond the kernel, about 2 lambda N / (pi^2 R) for a kernel
    half-width R, is thereby put back into the kernel), and summed with ``weights``
    (normalised; uniform if None). Jitter is then applied as a convolution with a Gaussian of
    per-axis std optics.jitter_rms_m, integrated over each sample. With defocus
    (optics.defocus_blur_diameter_m = d > 0) the kernel is convolved with the geometric blur
    disc (a pillbox of diameter d, uniform; see :func:`defocus_mtf`), each of its samples
    holding the exact area of the disc inside it (a disc of d <= one sample lies inside the
    centre sample and leaves the kernel unchanged); the discrete convolution adds the disc's
    variance d^2 / 16 per axis plus the sample's pitch^2 / 12 (binning). Power pushed off the
    kernel is given back by the final normalisation, so size_px should exceed
    d / sample_pitch_m by a few diffraction widths. Size must be odd; the PSF centre is the
    centre sample.
    """
    if isinstance(size_px, bool) or int(size_px) != size_px or size_px < 1 or size_px % 2 == 0:
        raise SatsightError(
            f"size_px must be a positive odd integer (so the PSF is centred); got {size_px!r}"
        )
    if isinstance(subsamples, bool) or int(subsamples) != subsamples or subsamples < 1:
        raise SatsightError(f"subsamples must be a positive integer; got {subsamples!r}")
    pitch = _check_positive("sample_pitch_m", sample_pitch_m, "m")
    lam, w = _spectral_weights(wavelengths_m, weights)
    size, n = int(size_px), int(subsamples)
    radius = size // 2
    centres = (np.arange(size) - radius) * pitch
    offsets = ((np.arange(n) + 0.5) / n - 0.5) * pitch
    coords = (centres[:, None] + offsets[None, :]).ravel()  # (size * n,)
    r = np.hypot(coords[:, None], coords[None, :])
    eps = optics.obscuration_ratio
    kernel = np.zeros((size, size))
    for lk, wk in zip(lam, w, strict=True):
        if wk == 0.0:
            continue
        intensity = _annular_airy_intensity(math.pi * r / (lk * optics.f_number), eps)
        binned = intensity.reshape(size, n, size, n).sum(axis=(1, 3))
        kernel += wk * binned / binned.sum()
    sigma = optics.jitter_rms_m / pitch
    if sigma > 0.0:
        g = _gaussian_kernel_1d(sigma, radius)
        kernel = fftconvolve(kernel, g[:, None] * g[None, :], mode="same")
        kernel = np.maximum(kernel, 0.0)
    blur_samples = optics.defocus_blur_diameter_m / pitch
    if blur_samples > 1.0:
        # Disc samples farther than 2 radius from the centre cannot carry kernel power back
        # onto the kernel, so the disc is cut there.
        half = min(math.ceil(0.5 * blur_samples + 0.5), 2 * radius)
        disc = _pillbox_kernel(blur_samples, half)
        kernel = np.maximum(fftconvolve(kernel, disc, mode="same"), 0.0)
    return kernel / kernel.sum()


# --- applying the optics to an image ---------------------------------------------------------


def apply_optics(
    irradiance_w_m2: np.ndarray,
    psf: np.ndarray,
    supersampling: int = 1,
    *,
    threads: int | None = None,
    signal_box: tuple[int, int, int, int] | None = None,
) -> np.ndarray:
    """Blur a supersampled focal-plane irradiance image by the PSF and bin it into pixels.

    irradiance_w_m2: (H * s, W * s) focal-plane irradiance (W m^-2) on the supersampled grid
    (s = supersampling). psf: 2-D kernel on the same grid, odd size, normally summing to 1
    (``psf_kernel``), so that power is conserved away from the borders. The convolution is
    the linear, "same"-size convolution of ``scipy.signal.fftconvolve(mode="same")`` (power
    that spreads beyond the frame is lost), computed by FFT in the image's precision (see
    ``fft_convolve_same``); then each s x s block is averaged, so each output pixel holds the
    pixel-averaged irradiance (W m^-2) and pixel power = value x pixel area. Only the
    bounding box of the non-zero input, padded by the kernel radius, is convolved (the rest
    of the frame is empty space and stays exactly 0); an all-zero frame returns zeros
    without convolving. FFT round-off below zero is clipped to 0. ``threads`` (default: all
    cores) does not change the result. ``signal_box`` = (row0, row1, col0, col1), end
    exclusive, on the supersampled grid: a box known to hold every non-zero sample, which
    saves the scan for it (a box too small loses light). Returns (H, W) in the input's float
    dtype.
    """
    img = np.asarray(irradiance_w_m2)
    kern = np.asarray(psf, dtype=np.float64)
    if img.ndim != 2 or not np.issubdtype(img.dtype, np.floating):
        raise SatsightError(
            "irradiance_w_m2 must be a 2-D float image (H*s, W*s); "
            f"got shape {img.shape}, dtype {img.dtype}"
        )
    if kern.ndim != 2 or kern.shape[0] % 2 == 0 or kern.shape[1] % 2 == 0:
        raise SatsightError(
            f"psf must be a 2-D kernel with odd sizes (centred); got shape {kern.shape}. "
            "Build it with psf_kernel(size_px=odd)."
        )
    if isinstance(supersampling, bool) or int(supersampling) != supersampling or supersampling < 1:
        raise SatsightError(f"supersampling must be a positive integer; got {supersampling!r}")
    n_threads = check_threads(threads)
    s = int(supersampling)
    hs, ws = img.shape
    if hs % s or ws % s:
        raise SatsightError(
            f"the supersampled image {img.shape} is not a whole number of {s} x {s} blocks; "
            "render at (H * s, W * s)."
        )
    out = np.zeros((hs // s, ws // s), dtype=img.dtype)
    if signal_box is None:
        rows = np.flatnonzero(np.any(img != 0, axis=1))
        if rows.size == 0:
            return out
        cols = np.flatnonzero(np.any(img[rows[0] : rows[-1] + 1] != 0, axis=0))
    else:
        b0, b1, b2, b3 = (int(v) for v in signal_box)
        if not (0 <= b0 < b1 <= hs and 0 <= b2 < b3 <= ws):
            raise SatsightError(
                f"signal_box must be (row0, row1, col0, col1) inside the {hs} x {ws} image "
                f"with row0 < row1 and col0 < col1; got {signal_box!r}"
            )
        rows, cols = np.array([b0, b1 - 1]), np.array([b2, b3 - 1])
    ry, rx = kern.shape[0] // 2, kern.shape[1] // 2
    # Window: signal bounding box padded by the kernel radius, widened to whole s-blocks.
    r0 = max(rows[0] - ry, 0) // s * s
    r1 = min(-(-(rows[-1] + 1 + ry) // s) * s, hs)
    c0 = max(cols[0] - rx, 0) // s * s
    c1 = min(-(-(cols[-1] + 1 + rx) // s) * s, ws)
    target = out[r0 // s : r1 // s, c0 // s : c1 // s]

    def finish(band_r0: int, blurred: np.ndarray) -> None:
        """Clip a band of blurred rows (a multiple of s) at 0, bin it into ``target``."""
        h, w = blurred.shape
        pixels = target[band_r0 // s : (band_r0 + h) // s]
        if s == 1:
            np.maximum(blurred, 0.0, out=pixels)
        else:
            np.maximum(blurred, 0.0, out=blurred)
            pixels[...] = blurred.reshape(h // s, s, w // s, s).mean(axis=(1, 3))

    fft_convolve_same(img[r0:r1, c0:c1], kern, threads=n_threads, row_multiple=s, sink=finish)
    return out


def fft_convolve_same(
    image: np.ndarray,
    kernel: np.ndarray,
    *,
    threads: int | None = None,
    row_multiple: int = 1,
    sink: Callable[[int, np.ndarray], None] | None = None,
) -> np.ndarray | None:
    """Linear convolution of ``image`` (H, W) with ``kernel`` (ky, kx), "same" size, by FFT.

    The same result as ``scipy.signal.fftconvolve(image, kernel, mode="same")`` up to FFT
    round-off (float32 images are transformed in single precision, as scipy does; float64 in
    double): out[i, j] = sum_ab image[i + (ky - 1) // 2 - a, j + (kx - 1) // 2 - b] k[a, b],
    zero outside the image. Both axes are zero-padded to 5-smooth lengths M >= H + ky - 1 and
    N >= W + kx - 1, so the cyclic convolution of the FFTs is the linear one. The work is
    split into fixed bands (a function of the sizes only) run on ``threads`` threads
    (default: all cores): real FFTs of row bands, then per band of columns the column FFT,
    the product with the kernel's spectrum and the inverse column FFT, then inverse real FFTs
    of row bands. The kernel's spectrum is made per column band from the real FFT of its ky
    rows, as scipy makes it (no BLAS call: OpenBLAS's own threads would compete with these).

    With ``sink``, each band of output rows (a multiple of ``row_multiple`` rows except at
    the end) is passed to ``sink(first_row, rows)`` as it is made, the rows being a scratch
    array it may change, and None is returned; else the (H, W) result is returned.
    """
    img = np.asarray(image)
    real = np.float32 if img.dtype == np.float32 else np.float64
    img = img.astype(real, copy=False)
    kern = np.asarray(kernel, dtype=np.float64)
    if img.ndim != 2 or kern.ndim != 2 or 0 in img.shape or 0 in kern.shape:
        raise SatsightError(
            f"image and kernel must be non-empty 2-D arrays; got {img.shape} and {kern.shape}"
        )
    n_threads = check_threads(threads)
    complex_dtype = np.complex64 if real is np.float32 else np.complex128
    h, w = img.shape
    ky, kx = kern.shape
    oy, ox = (ky - 1) // 2, (kx - 1) // 2
    m = scipy.fft.next_fast_len(h + ky - 1)
    n = scipy.fft.next_fast_len(w + kx - 1, real=True)
    nf = n // 2 + 1
    kern_rows = scipy.fft.rfft(kern.astype(real), n, axis=1)  # (ky, nf), as scipy does
    spectrum = np.empty((h, nf), dtype=complex_dtype)
    result = np.empty((h, w), dtype=real) if sink is None else None
    step = max(1, _FFT_BAND_ELEMENTS // n)
    step = max(row_multiple, step // row_multiple * row_multiple)
    row_bands = [(a, min(a + step, h)) for a in range(0, h, step)]
    col_step = max(1, _FFT_BAND_ELEMENTS // m)
    col_bands = [(a, min(a + col_step, nf)) for a in range(0, nf, col_step)]

    def forward(i: int) -> None:
        a, b = row_bands[i]
        padded = np.zeros((b - a, n), dtype=real)  # faster than rfft's own zero-padding
        padded[:, :w] = img[a:b]
        spectrum[a:b] = scipy.fft.rfft(padded, axis=1)

    def columns(i: int) -> None:
        a, b = col_bands[i]
        block = scipy.fft.fft(spectrum[:, a:b], m, axis=0)
        block *= scipy.fft.fft(kern_rows[:, a:b], m, axis=0)
        spectrum[:, a:b] = scipy.fft.ifft(block, axis=0, overwrite_x=True)[oy : oy + h]

    def inverse(i: int) -> None:
        a, b = row_bands[i]
        rows = scipy.fft.irfft(spectrum[a:b], n, axis=1)[:, ox : ox + w]
        if sink is None:
            result[a:b] = rows
        else:
            sink(a, rows)

    run_jobs(forward, len(row_bands), n_threads)
    run_jobs(columns, len(col_bands), n_threads)
    run_jobs(inverse, len(row_bands), n_threads)
    return result


# --- plot ------------------------------------------------------------------------------------


def plot_system_mtf(
    optics: Optics,
    pixel_pitch_m: float,
    band_nm: tuple[float, float] | None,
    path: str | Path,
    n_wavelengths: int = DEFAULT_N_WAVELENGTHS,
) -> Path:
    """Write a PNG of the diffraction, pixel, jitter and system MTF vs frequency (cycles/mm).

    The axis runs to 1.1 x the pixel Nyquist frequency 1 / (2 p), which is marked; the
    shortest-wavelength diffraction cut-off 1 / (lambda_min N) is marked when it is in range.
    With defocus (optics.defocus_blur_diameter_m > 0) its signed geometric OTF is drawn too,
    the system curve includes it (and is then the signed OTF) and the axis shows the negative
    lobes. Returns the path written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    lam = band_wavelengths_m(band_nm, n_wavelengths)
    nyquist = 1.0 / (2.0 * p)
    lo_nm, hi_nm = lam[0] * 1e9, lam[-1] * 1e9
    cutoff = 1.0 / (float(lam.min()) * optics.f_number)
    f = np.linspace(0.0, 1.1 * nyquist, 512)
    diff = np.mean(
        [diffraction_mtf(f, lk, optics.f_number, optics.obscuration_ratio) for lk in lam], axis=0
    )
    pix = pixel_mtf(f, p)
    jit = jitter_mtf(f, optics.jitter_rms_rad, optics.focal_length_m)
    d = optics.defocus_blur_diameter_m
    system = diff * pix * jit
    if d > 0.0:
        dfc = defocus_mtf(f, d)
        system = system * dfc
    f_mm = f * 1e-3
    fig, ax = plt.subplots(figsize=(7, 4.5))
    try:
        ax.plot(f_mm, diff, label=f"diffraction (f/{optics.f_number:.3g}, band-averaged)")
        ax.plot(f_mm, pix, label=f"pixel ({p * 1e6:.3g} um, 100 % fill)")
        ax.plot(f_mm, jit, label=f"jitter ({optics.jitter_rms_rad * 1e6:.3g} urad RMS)")
        if d > 0.0:
            ax.plot(f_mm, dfc, label=f"defocus ({d * 1e6:.3g} um blur disc, geometric OTF)")
        ax.plot(f_mm, system, "k", lw=2, label="system")
        ax.axvline(nyquist * 1e-3, color="gray", ls="--", label="Nyquist 1/(2p)")
        if cutoff < 1.1 * nyquist:
            ax.axvline(cutoff * 1e-3, color="red", ls=":", label="diffraction cut-off")
        ax.set_xlim(0.0, 1.1 * nyquist * 1e-3)
        if d > 0.0:  # the defocus OTF is signed: show its negative lobes
            ax.axhline(0.0, color="black", lw=0.5)
            ax.set_ylim(min(0.0, float(dfc.min()), float(system.min())) - 0.02, 1.02)
        else:
            ax.set_ylim(0.0, 1.02)
        ax.set_xlabel("spatial frequency in the focal plane (cycles/mm)")
        ax.set_ylabel("MTF" if d == 0.0 else "MTF (signed OTF where negative)")
        ax.set_title(f"System MTF, {lo_nm:.0f}-{hi_nm:.0f} nm sub-band centres")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=8)
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out, dpi=100)
    finally:
        plt.close(fig)
    return out
