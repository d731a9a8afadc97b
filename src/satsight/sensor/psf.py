"""Blur kernels: the pixel-integrated PSF of the optics, and the kernel for rendered frames.

Two kernels, for two kinds of input:

* :func:`psf_kernel`, the optics' polychromatic PSF integrated over square samples: the
  fraction of a point source's power that falls on each sample. PSF: Airy pattern, Born &
  Wolf, "Principles of Optics", 7th ed., Sec. 8.5.2 (83.8 % of the power inside the first dark
  ring), and its annular form (Mahajan, "Optical Imaging and Aberrations, Part II", Sec. 2.4).
* :func:`frame_kernel`, the discrete kernel that turns a rendered frame (point samples of the
  radiance at sub-pixel positions, averaged per pixel) into the pixel-averaged focal-plane
  image, designed in the frequency domain so that the frame's transfer function is the
  system OTF up to the pixel Nyquist frequency (see its docstring and docs/design.md).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np
import scipy.fft
from scipy.special import erf, j1

from satsight.errors import SatsightError
from satsight.sensor.mtf import (
    _spectral_weights,
    check_render_sampling,
    render_sampling_otf,
    system_otf_2d,
)
from satsight.sensor.optics import Optics, _check_positive

#: Frequency samples per pixel-rate period (per axis) of the frame kernel's design grid, per
#: kernel sample: the grid has at least 8 x size points, and 256.
_DESIGN_SAMPLES_PER_TAP = 8
_MIN_DESIGN_GRID = 256


def _check_kernel_size(size_px: int) -> int:
    if isinstance(size_px, bool) or int(size_px) != size_px or size_px < 1 or size_px % 2 == 0:
        raise SatsightError(
            f"size_px must be a positive odd integer (so the PSF is centred); got {size_px!r}"
        )
    return int(size_px)


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
    _check_kernel_size(size_px)
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
        kernel = _convolve_same(kernel, g[:, None] * g[None, :])
        kernel = np.maximum(kernel, 0.0)
    blur_samples = optics.defocus_blur_diameter_m / pitch
    if blur_samples > 1.0:
        # Disc samples farther than 2 radius from the centre cannot carry kernel power back
        # onto the kernel, so the disc is cut there.
        half = min(math.ceil(0.5 * blur_samples + 0.5), 2 * radius)
        disc = _pillbox_kernel(blur_samples, half)
        kernel = np.maximum(_convolve_same(kernel, disc), 0.0)
    return kernel / kernel.sum()


def _convolve_same(image: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Linear convolution of two small 2-D arrays by real FFTs on 5-smooth lengths, the
    central ``image.shape`` part ("same" size); the values of scipy.signal.fftconvolve
    (mode "same"), bit for bit, without importing scipy.signal (0.4 s at start-up)."""
    full_shape = [n + m - 1 for n, m in zip(image.shape, kernel.shape, strict=True)]
    fft_shape = [scipy.fft.next_fast_len(n, True) for n in full_shape]
    spectrum = scipy.fft.rfftn(image, fft_shape) * scipy.fft.rfftn(kernel, fft_shape)
    full = scipy.fft.irfftn(spectrum, fft_shape)[: full_shape[0], : full_shape[1]]
    top, left = ((f - n) // 2 for f, n in zip(full_shape, image.shape, strict=True))
    return full[top : top + image.shape[0], left : left + image.shape[1]]


def frame_kernel(
    optics: Optics,
    wavelengths_m: Sequence[float] | np.ndarray | float,
    weights: Sequence[float] | np.ndarray | None,
    pixel_pitch_m: float,
    size_px: int,
    supersampling: int = 1,
    samples_per_pixel: int = 1,
) -> np.ndarray:
    """Kernel (size_px, size_px), float64, summing to 1, for rendered frames at pixel pitch.

    A rendered pixel is the mean of point samples of the radiance at the renderer's sub-pixel
    positions (``supersampling`` s, ``samples_per_pixel``), whose expected transfer function
    is S(fx) S(fy) (:func:`satsight.sensor.mtf.render_sampling_otf`: 1 for one centre sample).
    The camera's image is the radiance blurred by the system OTF H(fx, fy)
    (:func:`satsight.sensor.mtf.system_otf_2d`: diffraction of the pupil averaged over
    ``wavelengths_m`` with ``weights``, pixel aperture, jitter, defocus). The kernel k[m]
    convolved with the rendered frame must then have the discrete-time Fourier transform

        K(fx, fy) = sum_m k[m] exp(-2 pi i p f.m) = H(fx, fy) / (S(fx) S(fy))

    on the Nyquist square |fx|, |fy| <= 1 / (2 p), so that the frame's response K S is H
    there; K repeats with period 1 / p. Its taps are the Fourier coefficients of K,

        k[m] = p^2 integral over the square of K(f) exp(2 pi i p f.m) df,

    computed as the inverse 2-D DFT of K sampled on an n x n grid of the square (n >= 8 x
    size_px and >= 256; this adds the taps' aliases k[m + n l], ~1e-6 of the power), then cut to
    size_px x size_px around the centre (the window method of FIR filter design: Oppenheim &
    Schafer, "Discrete-Time Signal Processing", 3rd ed., Sec. 7.5; Lim, "Two-Dimensional Signal
    and Image Processing" (1990), Sec. 4.3), made exactly symmetric and divided by their sum.

    What the cut costs: K's periodic extension has a kink at the Nyquist lines (H / S falls
    towards them from both sides), so the taps fall off as 1 / m^2 along the axes and, with
    alternating signs, beyond the cut; a kernel of half-width R rounds the kink, raising the
    response at Nyquist by about 0.36 / R relative (1.5 % at f/7, 1.8 % at f/10 for R = 20,
    s = 1) and by < 0.7 % at up to 0.95 x Nyquist. The division by the sum puts the power of
    the far Airy wings (~2 lambda N / (pi^2 R p)) back into the kernel, which raises the
    response above the lowest frequencies by that fraction (0.3-0.5 %). Some taps are
    negative (down to -1.3 % of the power at two pixels from the centre, -9 % in all, for
    s = 1), as they must be where a point-sampled frame is turned into a blurred one; at a
    straight edge against black space they undershoot by ~1e-4 of the step, so clipping at 0
    after the convolution (``apply_optics``) changes little, but an isolated bright pixel
    gains up to the negative taps' share (9 %) from the clipping. Size must be odd.
    """
    size = _check_kernel_size(size_px)
    s, spp = check_render_sampling(supersampling, samples_per_pixel)
    pitch = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    lam, w = _spectral_weights(wavelengths_m, weights)
    kernel = _frame_kernel(optics, tuple(lam.tolist()), tuple(w.tolist()), pitch, size, s, spp)
    return kernel.copy()


@functools.lru_cache(maxsize=16)
def _frame_kernel(
    optics: Optics,
    wavelengths_m: tuple[float, ...],
    weights: tuple[float, ...],
    pixel_pitch_m: float,
    size: int,
    supersampling: int,
    samples_per_pixel: int,
) -> np.ndarray:
    """:func:`frame_kernel` for hashable, checked arguments (cached; read-only result)."""
    n = max(_MIN_DESIGN_GRID, _DESIGN_SAMPLES_PER_TAP * size)
    n = 1 << (n - 1).bit_length()  # a power of two, even: the grid holds -Nyquist
    # K is even in fx and fy: evaluate it at the frequencies j / (n p), j = 0 .. n / 2 (up to
    # Nyquist), and mirror it onto j = -n / 2 .. n / 2 - 1.
    f = np.arange(n // 2 + 1) / (n * pixel_pitch_m)
    otf = system_otf_2d(f[None, :], f[:, None], optics, pixel_pitch_m, wavelengths_m, weights)
    sampling = render_sampling_otf(f, pixel_pitch_m, supersampling, samples_per_pixel)
    quadrant = otf / (sampling[:, None] * sampling[None, :])
    mirror = np.abs(np.arange(n) - n // 2)
    designed = quadrant[mirror][:, mirror]
    taps = np.fft.fftshift(np.fft.ifft2(np.fft.ifftshift(designed)).real)
    c, r = n // 2, size // 2
    # K is even in fx and fy and symmetric in (fx, fy): the taps are made exactly so, from
    # the mean of their four quadrants (centre row and column included), symmetrised.
    quadrant = 0.25 * (
        taps[c : c + r + 1, c : c + r + 1]
        + taps[c : c - r - 1 : -1, c : c + r + 1]
        + taps[c : c + r + 1, c : c - r - 1 : -1]
        + taps[c : c - r - 1 : -1, c : c - r - 1 : -1]
    )
    quadrant = 0.5 * (quadrant + quadrant.T)
    fold = np.abs(np.arange(-r, r + 1))
    kernel = quadrant[fold][:, fold]
    kernel = kernel / kernel.sum()
    kernel.setflags(write=False)
    return kernel
