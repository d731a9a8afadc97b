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
from threadpoolctl import threadpool_limits

from satsight.errors import SatsightError
from satsight.sensor.mtf import (
    _spectral_weights,
    check_render_sampling,
    render_sampling_otf,
    system_otf_2d,
)
from satsight.sensor.optics import Optics, _check_positive

#: Frequency samples of the frame kernel's design grid over [0, Nyquist] per axis, per tap of
#: its half-width (and at least _MIN_DESIGN_POINTS): 4 per tap resolve the cosines of the
#: outermost taps (period 1 / r) with 8 points per period over the full pixel-rate period.
_DESIGN_POINTS_PER_TAP = 4
_MIN_DESIGN_POINTS = 65
#: Weight of the axes' (fx = 0 or fy = 0) errors against the rest of the Nyquist square.
_AXIS_WEIGHT = 30.0
#: Weight of the response at f = 0 (held at 1; the final division by the sum makes it exact).
_DC_WEIGHT = 1e4
#: Floor of |K| in the relative-error weight 1 / |K| (where the OTF nears 0, e.g. defocus).
_RELATIVE_FLOOR = 0.25
#: Lawson iterations of the weights on the axes (the first is the plain weighted design).
_LAWSON_ITERATIONS = 8


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
    there; K repeats with period 1 / p. The truncated Fourier series of K (the window
    method, Oppenheim & Schafer, "Discrete-Time Signal Processing", 3rd ed., Sec. 7.5) rounds
    the kink of K's periodic extension at the Nyquist lines and read 1.5-1.8 % high there.
    Instead the size_px x size_px taps (8-fold symmetric) are fitted by weighted least
    squares to K on a grid of the square's quadrant (4 points per tap of half-width r, at
    least 65 per axis): each point weighted by 1 / max(|K|, 0.25) (a relative error where the
    response is not near a zero), the axes fx = 0 and fy = 0 (where an edge's MTF is read)
    30 times more, and on the axes Lawson's iteration (weights times |error|, 8 rounds;
    Burrus, Barreto & Selesnick, IEEE Trans. Signal Process. 42, 2926 (1994)) turning the
    least squares into a near-minimax fit. The taps are divided by their sum (K(0) = 1).
    Measured along an axis for R = 20, one centre sample: within 0.57 % (f/7) and 0.63 %
    (f/10) of H at every frequency up to Nyquist (0.48 / 0.53 % at Nyquist), and within 0.005
    of H anywhere on the square.

    Some taps are negative (down to -1.25 % of the power at two pixels from the centre, -9.6 %
    in all at f/7, for s = 1), as they must be where a point-sampled frame is turned into a
    blurred one: the blurred frame dips below 0 next to bright, isolated pixels.
    ``apply_optics`` moves those dips onto the positive pixels around them (the sum kept)
    instead of clipping them away. Size must be odd.
    """
    size = _check_kernel_size(size_px)
    s, spp = check_render_sampling(supersampling, samples_per_pixel)
    pitch = _check_positive("pixel_pitch_m", pixel_pitch_m, "m")
    lam, w = _spectral_weights(wavelengths_m, weights)
    kernel = _frame_kernel(optics, tuple(lam.tolist()), tuple(w.tolist()), pitch, size, s, spp)
    return kernel.copy()


def _symmetric_cosine_basis(u: np.ndarray, r: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Design matrix of an 8-fold symmetric kernel of half-width r on the grid u x u.

    Unknowns: the taps q[a, b], 0 <= a <= b <= r (q[b, a] = q[a, b], mirrored into all four
    quadrants). Column (a, b) is the DTFT of that tap orbit at (fx = u_j, fy = u_i), row
    i * len(u) + j: c_a(fy) c_b(fx) (+ c_b(fy) c_a(fx) for a < b), c_0 = 1 and
    c_a(u) = 2 cos(2 pi a u) (the pair at +-a).
    """
    a = np.arange(r + 1)
    c = np.cos(2.0 * math.pi * np.outer(u, a)) * np.where(a > 0, 2.0, 1.0)
    pairs = [(i, j) for i in range(r + 1) for j in range(i, r + 1)]
    columns = np.empty((u.size * u.size, len(pairs)))
    for k, (i, j) in enumerate(pairs):
        block = np.outer(c[:, i], c[:, j])
        if i != j:
            block = block + block.T
        columns[:, k] = block.ravel()
    return columns, pairs


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
    r = size // 2
    u = np.linspace(0.0, 0.5, max(_MIN_DESIGN_POINTS, _DESIGN_POINTS_PER_TAP * r + 1))
    f = u / pixel_pitch_m
    otf = system_otf_2d(f[None, :], f[:, None], optics, pixel_pitch_m, wavelengths_m, weights)
    sampling = render_sampling_otf(f, pixel_pitch_m, supersampling, samples_per_pixel)
    target = otf / (sampling[:, None] * sampling[None, :])  # [fy, fx], K's wanted values
    basis, pairs = _symmetric_cosine_basis(u, r)
    # Relative error everywhere (1 / |K|, floored where the OTF nears 0); the axes, where
    # an edge's MTF is read, count _AXIS_WEIGHT times more, and there Lawson's update
    # (w <- w |e|, renormalised) moves the weighted least squares towards the minimax.
    base = 1.0 / np.maximum(np.abs(target), _RELATIVE_FLOOR)
    axis = np.ones(u.size)
    # BLAS and LAPACK split their work by thread, which would change the last bits of the
    # taps (and through them a DN here and there) with the core count: one thread, so the
    # taps are the same on any machine with this BLAS.
    # The weights differ from base only on the axes (row fy = 0 and column fx = 0 of the
    # grid): the normal equations of base are formed once, and each Lawson step adds the
    # axes' change, a rank-(2n - 1) update (8 times less work than forming them anew).
    n = u.size
    on_axes = np.concatenate([np.arange(n), np.arange(1, n) * n])
    base2 = base.ravel() ** 2
    values = target.ravel()
    axes_basis = basis[on_axes]
    with threadpool_limits(limits=1):
        normal0 = basis.T @ (basis * base2[:, None])
        rhs0 = basis.T @ (values * base2)
        for _ in range(_LAWSON_ITERATIONS):
            weight = base.copy()
            weight[0, :] *= _AXIS_WEIGHT * axis
            weight[:, 0] *= _AXIS_WEIGHT * axis
            weight[0, 0] = _DC_WEIGHT  # K(0) = 1: the blur keeps the power
            change = weight.ravel()[on_axes] ** 2 - base2[on_axes]
            normal = normal0 + axes_basis.T @ (axes_basis * change[:, None])
            rhs = rhs0 + axes_basis.T @ (values[on_axes] * change)
            taps = np.linalg.solve(normal, rhs)
            error = np.abs(basis[:n] @ taps - target[0]) * base[0]  # relative, on fy = 0
            axis = axis * np.sqrt(error / error.max()) + 1e-9
            axis /= axis.mean()
    quadrant = np.zeros((r + 1, r + 1))
    for k, (i, j) in enumerate(pairs):
        quadrant[i, j] = quadrant[j, i] = taps[k]
    fold = np.abs(np.arange(-r, r + 1))
    kernel = quadrant[fold][:, fold]
    kernel = kernel / kernel.sum()
    kernel.setflags(write=False)
    return kernel
