"""Blur kernels: the pixel-integrated PSF of the optics and the kernel for rendered frames.

Oracles: Born & Wolf Sec. 8.5.2 Airy encircled energy 1 - J0^2(v) - J1^2(v); Mahajan's annular
encircled energy by radial quadrature of the analytic intensity; the FFT of the sampled PSF;
second moments that add under convolution; the system OTF and the renderer's sampling
response (``satsight.sensor.mtf``) for the frame kernel's discrete-time Fourier transform.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.special import j0, j1, jv

from kernel_taps import frame_kernel_taps
from satsight.errors import SatsightError
from satsight.sensor.mtf import (
    band_wavelengths_m,
    defocus_mtf,
    diffraction_mtf,
    render_sampling_otf,
    system_mtf,
    system_otf_2d,
)
from satsight.sensor.optics import Optics
from satsight.sensor.psf import frame_kernel, psf_kernel

REL = 1e-12  # closed forms evaluated the same way up to float64 rounding
LAM_M = 550e-9
N = 10.0
OPTICS = Optics(aperture_diameter_m=0.3, focal_length_m=3.0)  # f/10
FIRST_ZERO_V = 3.8317059702075125  # first zero of J1
AIRY_EE_FIRST_RING = 1.0 - j0(FIRST_ZERO_V) ** 2  # 0.8378, Born & Wolf Sec. 8.5.2


def encircled_energy(v: float, eps: float) -> float:
    """Fraction of the power inside radius v = pi r / (lambda N), by radial quadrature.

    With the pupil-area normalisation, EE(v) = (1 - eps^2) / 2 * int_0^v a(t)^2 t dt, where
    a(t) = [2J1(t)/t - eps^2 2J1(eps t)/(eps t)] / (1 - eps^2) (Mahajan Part II Sec. 2.4).
    """

    def integrand(t: float) -> float:
        if t == 0.0:
            return 0.0
        amp = 2 * j1(t) / t - (eps * eps * 2 * j1(eps * t) / (eps * t) if eps > 0 else 0.0)
        return (amp / (1 - eps * eps)) ** 2 * t

    breaks = np.arange(0.0, v, math.pi)
    total = sum(
        integrate.quad(integrand, a, min(a + math.pi, v), epsabs=1e-13, epsrel=1e-12)[0]
        for a in breaks
    )
    return (1 - eps * eps) / 2 * total


# --- PSF ---------------------------------------------------------------------------------------


def test_psf_normalised_symmetric_centred():
    lam = band_wavelengths_m((450.0, 900.0), 8)
    k = psf_kernel(Optics(0.3, 3.0, jitter_rms_rad=0.5e-6), lam, None, 5e-6, 15)
    assert k.shape == (15, 15)
    assert k.sum() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(k, k[::-1, :], atol=1e-15)
    np.testing.assert_allclose(k, k[:, ::-1], atol=1e-15)
    np.testing.assert_allclose(k, k.T, atol=1e-15)
    assert np.unravel_index(np.argmax(k), k.shape) == (7, 7)
    assert np.all(k >= 0)
    with pytest.raises(SatsightError, match="size_px must be a positive odd integer"):
        psf_kernel(OPTICS, lam, None, 5e-6, 16)


def _ring_fraction(kernel: np.ndarray, pitch_m: float, radius_m: float) -> float:
    c = kernel.shape[0] // 2
    y, x = np.indices(kernel.shape) - c
    return float(kernel[np.hypot(x, y) * pitch_m <= radius_m].sum())


@pytest.mark.parametrize("eps", [0.0, 0.3])
def test_psf_encircled_energy(eps):
    # Monochromatic PSF, pitch lambda N / 8, half-width 40 lambda N (641 x 641 samples). The
    # kernel is normalised on its support, so the measured fraction lies between EE(r) and
    # EE(r) / EE(R_in), R_in = the inscribed radius (the power beyond it is at most
    # 1 - EE(R_in), about 2 / (pi v) = 0.5 %). The first dark ring carries ~zero intensity,
    # so samples straddling it add an error well below 1e-3.
    pitch = LAM_M * N / 8
    size = 641
    optics = Optics(0.3, 3.0, obscuration_ratio=eps)
    k = psf_kernel(optics, [LAM_M], None, pitch, size, subsamples=3)
    r_ring = FIRST_ZERO_V / math.pi * LAM_M * N
    measured = _ring_fraction(k, pitch, r_ring)
    ee_ring = encircled_energy(FIRST_ZERO_V, eps)
    v_in = math.pi * (size // 2) * pitch / (LAM_M * N)
    ee_in = encircled_energy(v_in, eps)
    assert ee_ring - 1e-3 <= measured <= ee_ring / ee_in + 1e-3
    if eps == 0.0:
        assert ee_ring == pytest.approx(AIRY_EE_FIRST_RING, abs=1e-9)  # quadrature vs closed form
        assert measured == pytest.approx(0.838, abs=0.005)
    else:
        assert ee_ring < AIRY_EE_FIRST_RING - 0.05  # the obscuration pushes power into the rings


def test_psf_fft_matches_diffraction_mtf():
    # Monochromatic clear pupil, pitch lambda N / 4 (Nyquist 2 / (lambda N) > cut-off, so no
    # aliasing). The 3-point midpoint rule multiplies the OTF by sin(pi f p) / (3 sin(pi f p / 3))
    # exactly. Normalising the truncated kernel changes the OTF by at most twice the power
    # outside it, 2 (1 - EE(R_in)).
    pitch = LAM_M * N / 4
    size = 321
    k = psf_kernel(OPTICS, [LAM_M], None, pitch, size, subsamples=3)
    otf = np.abs(np.fft.fft(k.sum(axis=0)))  # f_y = 0 section of the 2-D OTF
    f = np.fft.fftfreq(size, d=pitch)[: size // 2]
    box = np.sin(np.pi * f * pitch) / (3 * np.sin(np.pi * f * pitch / 3) + (f == 0)) + (f == 0)
    expected = diffraction_mtf(f, LAM_M, N) * np.abs(box)
    v_in = math.pi * (size // 2) * pitch / (LAM_M * N)
    tol = 2 * (1 - encircled_energy(v_in, 0.0))
    assert tol < 0.012
    np.testing.assert_allclose(otf[: size // 2], expected, rtol=0, atol=tol)


def test_psf_jitter_adds_variance():
    # Variances add under convolution: the jitter Gaussian integrated over each sample has
    # variance sigma^2 + pitch^2 / 12 (Sheppard's correction, exact to ~1e-10 relative for
    # sigma = 3 samples). The kernel is cropped to its support after the jitter blur, which
    # drops the part of the outermost Airy wing pushed off the kernel; with lambda N = 0.8 um
    # and a 100 um half-width that wing holds ~2 lambda N / (pi^2 R) = 0.16 % of the power, so
    # the measured variance gain is good to a few 1e-3: 5e-3 relative.
    pitch = 5e-6
    optics = Optics(aperture_diameter_m=1.0, focal_length_m=1.5, jitter_rms_rad=1e-5)
    sharp = Optics(aperture_diameter_m=1.0, focal_length_m=1.5)
    x = (np.arange(41) - 20) * pitch

    def variance_x(o: Optics) -> float:
        return float((psf_kernel(o, [LAM_M], None, pitch, 41).sum(axis=0) * x**2).sum())

    gain = variance_x(optics) - variance_x(sharp)
    assert gain == pytest.approx(optics.jitter_rms_m**2 + pitch**2 / 12, rel=5e-3)


def _pillbox_alias_variance(d: float, terms: int = 100_000) -> float:
    """Aliasing term of the per-axis second moment of a disc of diameter d (samples) that is
    area-averaged over unit samples and summed at the sample centres.

    By Poisson summation, sum_n n^2 b(n) = sum_k FT[x^2 b](k), b = marginal of the disc * unit
    box; the k = 0 term is d^2 / 16 + 1 / 12, the others are (-1)^k (P(k) / k^2 - P'(k) / k)
    / (2 pi^2) with P(nu) = 2 J1(pi d nu) / (pi d nu) and P' = -2 pi d J2(u) / u. The series
    alternates; the mean of the last two partial sums converges far below 1e-9.
    """
    k = np.arange(1, terms + 1, dtype=np.float64)
    u = math.pi * d * k
    p, dp = 2 * j1(u) / u, -2 * math.pi * d * jv(2, u) / u
    partial = np.cumsum((-1.0) ** k * (p / k**2 - dp / k) / (2 * math.pi**2))
    return float(partial[-1] + partial[-2])  # 2 x (mean of the last two): both signs of k


def test_psf_defocus_disc_adds_its_second_moment():
    # A blur disc of d = 6 samples on an f/1 telescope at 550 nm (lambda N = 0.11 sample, so
    # the diffraction core sits in one sample). Second moments add under convolution: the
    # gain in <r^2> is the disc's d^2 / 8, plus 2 x 1 / 12 (the disc area-averaged over a
    # sample, Sheppard) plus the aliasing of sampling that binned disc at the sample centres
    # (Poisson summation, 2 x 0.0265 samples^2 here). Cut-off: the Airy wings hold
    # 2 lambda N / (pi^2 r) of the power beyond r; the disc moves the part within d / 2 of
    # the kernel edge R off the kernel, which changes <r^2> by at most
    # R^2 (2 lambda N / pi^2) (1 / (R - d / 2) - 1 / R) = 0.079 samples^2 (1.7 %).
    pitch, d_samples, size = 5e-6, 6.0, 41
    lam_n = LAM_M * 1.0 / pitch  # lambda N in samples
    sharp = Optics(aperture_diameter_m=1.0, focal_length_m=1.0)
    blurred = Optics(1.0, 1.0, defocus_blur_diameter_m=d_samples * pitch)
    y, x = np.indices((size, size)) - size // 2
    r2 = x * x + y * y
    k_sharp = psf_kernel(sharp, [LAM_M], None, pitch, size)
    k_blur = psf_kernel(blurred, [LAM_M], None, pitch, size)
    assert k_blur.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(k_blur >= 0.0)
    np.testing.assert_allclose(k_blur, k_blur.T, atol=1e-15)
    np.testing.assert_allclose(k_blur, k_blur[::-1, ::-1], atol=1e-15)
    gain = float((k_blur * r2).sum() - (k_sharp * r2).sum())
    alias = 2 * _pillbox_alias_variance(d_samples)
    assert alias == pytest.approx(0.05296, abs=1e-4)
    edge = size // 2
    tol = edge**2 * (2 * lam_n / math.pi**2) * (1 / (edge - d_samples / 2) - 1 / edge)
    assert tol < 0.08
    assert gain == pytest.approx(d_samples**2 / 8 + 1 / 6 + alias, abs=tol)
    # The uniform disc's own <r^2> = d^2 / 8 is what remains after the sampling terms.
    assert gain - 1 / 6 - alias == pytest.approx(d_samples**2 / 8, rel=0.02)
    # Inside the disc, away from its edge, the kernel is flat at 1 / (pi d^2 / 4) per sample.
    inner = r2 <= 1
    np.testing.assert_allclose(k_blur[inner], 4 / (math.pi * d_samples**2), rtol=0.01)


def test_psf_defocus_zero_or_subsample_leaves_the_kernel_bit_identical():
    lam = band_wavelengths_m((450.0, 900.0), 8)
    base = psf_kernel(Optics(0.3, 3.0, jitter_rms_rad=0.5e-6), lam, None, 5e-6, 15)
    for d in (0.0, 4e-6):  # a disc of d <= one sample lies inside the centre sample
        o = Optics(0.3, 3.0, jitter_rms_rad=0.5e-6, defocus_blur_diameter_m=d)
        assert psf_kernel(o, lam, None, 5e-6, 15).tobytes() == base.tobytes()


def test_psf_defocus_kernel_otf_is_the_sampled_disc_transform():
    # Along f_y = 0, FFT(defocused kernel) / FFT(focused kernel) is the transform of the disc
    # area-averaged over a sample and sampled at the centres: the aliases
    # sum_k P(f - k / p) sinc(p f - k) of the pillbox OTF P(f) = 2 J1(pi d f) / (pi d f)
    # (Poisson summation), real and signed. What differs is the focused kernel's Airy wing
    # that the disc pushes off the kernel: power (2 lambda N / pi^2)(1 / (R - d / 2) - 1 / R)
    # for a half-width R (4e-5 here), counted twice as a bound on the ratio's error.
    pitch, d_samples, size = 5e-6, 8.5, 101
    d = d_samples * pitch
    lam_n, edge = LAM_M * 1.0 / pitch, size // 2
    sharp = psf_kernel(Optics(1.0, 1.0), [LAM_M], None, pitch, size)
    blur = psf_kernel(Optics(1.0, 1.0, defocus_blur_diameter_m=d), [LAM_M], None, pitch, size)
    f = np.fft.rfftfreq(size, d=pitch)  # up to the sampling Nyquist 1 / (2 p)
    ratio = np.fft.rfft(blur.sum(axis=0)) / np.fft.rfft(sharp.sum(axis=0))
    aliased = sum(
        defocus_mtf(f - k / pitch, d) * np.sinc(f * pitch - k) for k in range(-2000, 2001)
    )
    tol = 2 * (2 * lam_n / math.pi**2) * (1 / (edge - d_samples / 2) - 1 / edge)
    assert tol < 1e-4
    np.testing.assert_allclose(ratio.real, aliased, rtol=0, atol=tol)
    assert np.abs(ratio.imag).max() < 1e-12  # symmetric kernel: a real, signed OTF
    assert ratio.real.min() < -0.05  # the contrast reversal past 3.83 / (pi d) is kept


# --- frame kernel ------------------------------------------------------------------------------

PITCH_M = 15e-6
BAND = band_wavelengths_m((450.0, 900.0))
FRAME_KERNEL_PX = 41  # the sensor chain's default (satsight.sensor.chain.PSF_SIZE_PX)


def _kernel_response(kernel: np.ndarray, u: np.ndarray) -> np.ndarray:
    """DTFT K(fx, fy) of a centred, symmetric kernel on the grid u x u (cycles per pixel)."""
    m = np.arange(kernel.shape[0]) - kernel.shape[0] // 2
    c = np.cos(2 * np.pi * np.outer(u, m))  # the kernel is even: cosines only
    return c @ kernel @ c.T  # [fy, fx]


@pytest.mark.parametrize("preset", ["wide_field", "high_resolution"])
@pytest.mark.parametrize("sampling", [(1, 1), (2, 1), (1, 16)], ids=["s1", "s2", "s1_spp16"])
def test_frame_kernel_times_the_sampling_response_is_the_system_otf(preset, sampling):
    # Over the Nyquist square, K(f) S(fx) S(fy) must equal H(f). 41 x 41 taps cannot follow
    # the kink of K's periodic extension at the Nyquist lines exactly; the weighted, near-
    # minimax design keeps the error along the axes (where an edge's MTF is read) within
    # 0.57 % (f/7) / 0.63 % (f/10) up to and including Nyquist (bound: the 1 % budget), and
    # anywhere on the square within 0.005 of H (bound 0.0075; H >= 0.24 there).
    optics = Optics.for_preset(preset)
    s, spp = sampling
    kernel = frame_kernel(optics, BAND, None, PITCH_M, FRAME_KERNEL_PX, s, spp)
    u = np.linspace(0.0, 0.5, 101)
    f = u / PITCH_M
    response = render_sampling_otf(f, PITCH_M, s, spp)
    measured = _kernel_response(kernel, u) * response[:, None] * response[None, :]
    expected = system_otf_2d(f[None, :], f[:, None], optics, PITCH_M, BAND)
    np.testing.assert_allclose(measured, expected, rtol=0, atol=0.0075)
    # The frame's MTF along either axis against the 1-D system MTF, the independent form.
    mtf = system_mtf(f, optics, PITCH_M, BAND)
    np.testing.assert_allclose(measured[0], mtf, rtol=0.01, atol=0)
    np.testing.assert_allclose(measured[:, 0], mtf, rtol=0.01, atol=0)


def test_frame_kernel_beats_the_truncated_fourier_series_at_nyquist():
    # The window method (the taps of K's Fourier series, cut to 41 x 41; kernel_taps, by
    # quadrature) reads 1.5 % (f/7) / 1.8 % (f/10) high at Nyquist; the designed kernel is
    # within 1 % there and at every frequency below.
    for preset in ("wide_field", "high_resolution"):
        optics = Optics.for_preset(preset)
        h = float(system_mtf(0.5 / PITCH_M, optics, PITCH_M, BAND))
        m = np.arange(FRAME_KERNEL_PX) - FRAME_KERNEL_PX // 2
        window = frame_kernel_taps(optics, BAND, PITCH_M, FRAME_KERNEL_PX)
        designed = frame_kernel(optics, BAND, None, PITCH_M, FRAME_KERNEL_PX)
        at_nyquist = [
            float((k.sum(axis=0) * np.cos(np.pi * m)).sum()) / h - 1 for k in (window, designed)
        ]
        assert 0.014 < at_nyquist[0] < 0.019
        assert abs(at_nyquist[1]) < 0.01


@pytest.mark.parametrize("sampling", [(1, 1), (2, 1), (1, 16)])
def test_frame_kernel_sums_to_one_is_symmetric_and_peaks_at_the_centre(sampling):
    optics = Optics.for_preset("wide_field", obscuration_ratio=0.3, jitter_rms_rad=0.5e-6)
    k = frame_kernel(optics, BAND, None, PITCH_M, FRAME_KERNEL_PX, *sampling)
    assert k.shape == (41, 41)
    assert k.sum() == pytest.approx(1.0, abs=1e-12)  # energy conservation
    np.testing.assert_array_equal(k, k[::-1, :])
    np.testing.assert_array_equal(k, k[:, ::-1])
    np.testing.assert_array_equal(k, k.T)
    assert np.unravel_index(np.argmax(k), k.shape) == (20, 20)
    # The returned array is the caller's: changing it leaves the cached design alone.
    k[20, 20] = 0.0
    again = frame_kernel(optics, BAND, None, PITCH_M, FRAME_KERNEL_PX, *sampling)
    assert again[20, 20] > 0.5


def test_frame_kernel_negative_taps_are_the_figures_of_the_design_notes():
    # One centre sample: the figures docs/design.md quotes ("Negative taps and the clip at
    # 0"), from the taps' defining integral, each to half a unit of its last quoted digit.
    # The band-limited PSF that a point-sampled frame needs has negative side lobes.
    for preset, centre_tap, negative_sum in (
        ("wide_field", -0.0126, -0.089),
        ("high_resolution", -0.0116, -0.082),
    ):
        q = frame_kernel_taps(Optics.for_preset(preset), BAND, PITCH_M, FRAME_KERNEL_PX)
        # The most negative tap: two pixels from the centre (equal to rounding on each axis).
        assert q.min() == pytest.approx(q[20, 22], abs=1e-15)
        assert q[20, 22] == pytest.approx(centre_tap, abs=0.00005)
        assert q[q < 0].sum() == pytest.approx(negative_sum, abs=0.0005)
        # A straight edge barely undershoots (design notes: ~1.3e-4 of the step): the step
        # response along a row, the running sum of the column sums, dips below 0 by less
        # than 2e-4.
        assert -2e-4 < np.cumsum(q.sum(axis=0)).min() < 0


def test_frame_kernel_rejects_bad_sizes_and_sampling():
    optics = Optics.for_preset("wide_field")
    with pytest.raises(SatsightError, match="odd"):
        frame_kernel(optics, BAND, None, PITCH_M, 40)
    with pytest.raises(SatsightError, match="supersampling"):
        frame_kernel(optics, BAND, None, PITCH_M, 41, 0, 1)
    with pytest.raises(SatsightError, match="samples_per_pixel"):
        frame_kernel(optics, BAND, None, PITCH_M, 41, 1, 0)


@pytest.mark.parametrize(("shape", "kernel_shape"), [((33, 33), (33, 33)), ((40, 41), (7, 12))])
def test_the_kernels_convolution_is_scipys_fftconvolve_bit_for_bit(shape, kernel_shape):
    """The jitter and defocus convolutions of the PSF kernel give scipy.signal.fftconvolve's
    values (mode "same") exactly, so the kernels keep their bits without scipy.signal."""
    from scipy.signal import fftconvolve

    from satsight.sensor.psf import _convolve_same

    rng = np.random.default_rng(5)
    image, kernel = rng.random(shape), rng.random(kernel_shape)
    np.testing.assert_array_equal(
        _convolve_same(image, kernel), fftconvolve(image, kernel, mode="same")
    )
