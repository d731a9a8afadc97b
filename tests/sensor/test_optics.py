"""Telescope optics: camera equation, MTF components, PSF and applying the blur.

Oracles: closed forms (Goodman Sec. 6.4 clear-pupil OTF; O'Neill 1956 annular OTF; Born & Wolf
Sec. 8.5.2 Airy encircled energy 1 - J0^2(v) - J1^2(v); Mahajan's annular encircled energy by
radial quadrature of the analytic intensity), an FFT autocorrelation of a pixelised pupil, the
FFT of the sampled PSF, and direct full-frame convolution.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.signal import convolve2d, fftconvolve
from scipy.special import j0, j1, jv

from satsight.errors import SatsightError
from satsight.sensor.optics import (
    DEFAULT_APERTURE_DIAMETER_M,
    Optics,
    apply_optics,
    band_wavelengths_m,
    defocus_mtf,
    diffraction_mtf,
    fft_convolve_same,
    focal_plane_irradiance_w_m2,
    jitter_mtf,
    pixel_mtf,
    plot_system_mtf,
    psf_kernel,
    system_mtf,
)

REL = 1e-12  # closed forms evaluated the same way up to float64 rounding
LAM_M = 550e-9
N = 10.0
OPTICS = Optics(aperture_diameter_m=0.3, focal_length_m=3.0)  # f/10
CUTOFF_CYC_PER_M = 1.0 / (LAM_M * N)
FIRST_ZERO_V = 3.8317059702075125  # first zero of J1
AIRY_EE_FIRST_RING = 1.0 - j0(FIRST_ZERO_V) ** 2  # 0.8378, Born & Wolf Sec. 8.5.2


def clear_mtf_closed_form(x: np.ndarray) -> np.ndarray:
    return (2.0 / np.pi) * (np.arccos(x) - x * np.sqrt(1.0 - x * x))


def oneill_annular_mtf(nu: np.ndarray, e: float) -> np.ndarray:
    """O'Neill (1956) annular-pupil OTF, written out independently of the module, 0 <= nu < 1."""
    a = clear_mtf_closed_form(nu)
    b = np.zeros_like(nu)
    m = nu <= e
    q = nu[m] / e
    b[m] = e * e * clear_mtf_closed_form(q)
    c = np.zeros_like(nu)
    c[nu <= (1 - e) / 2] = -2 * e * e
    m = (nu > (1 - e) / 2) & (nu < (1 + e) / 2)
    phi = np.arccos((1 + e * e - 4 * nu[m] ** 2) / (2 * e))
    c[m] = (
        -2 * e * e
        + (2 * e / np.pi) * np.sin(phi)
        + ((1 + e * e) / np.pi) * phi
        - (2 * (1 - e * e) / np.pi) * np.arctan((1 + e) / (1 - e) * np.tan(phi / 2))
    )
    return (a + b + c) / (1 - e * e)


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


# --- Optics -----------------------------------------------------------------------------------


def test_optics_defaults_and_f_number():
    assert OPTICS.f_number == pytest.approx(10.0, rel=REL)
    assert OPTICS.transmission == 0.8
    hr = Optics.for_preset("high_resolution")
    wf = Optics.for_preset("wide_field")
    assert hr.aperture_diameter_m == DEFAULT_APERTURE_DIAMETER_M["high_resolution"]
    assert hr.f_number == pytest.approx(10.0, rel=REL)
    assert wf.f_number == pytest.approx(7.0, rel=REL)
    assert Optics.for_preset("wide_field", jitter_rms_rad=1e-6).jitter_rms_m == pytest.approx(
        0.7e-6, rel=REL
    )


@pytest.mark.parametrize(
    "kwargs",
    [
        {"aperture_diameter_m": 0.0, "focal_length_m": 3.0},
        {"aperture_diameter_m": 0.3, "focal_length_m": -1.0},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "transmission": 80.0},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "obscuration_ratio": 1.0},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "jitter_rms_rad": -1e-6},
        {"aperture_diameter_m": 3.0, "focal_length_m": 0.3},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "defocus_blur_diameter_m": -1e-6},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "defocus_blur_diameter_m": math.nan},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "defocus_blur_diameter_m": math.inf},
        {"aperture_diameter_m": 0.3, "focal_length_m": 3.0, "defocus_blur_diameter_m": "far"},
    ],
)
def test_optics_rejects_bad_values(kwargs):
    with pytest.raises(SatsightError):
        Optics(**kwargs)


@pytest.mark.parametrize("bad", [-1e-6, math.nan, math.inf, None])
def test_defocus_rejects_bad_blur_diameters_with_a_hint(bad):
    with pytest.raises(SatsightError, match=r"defocus_blur_diameter_m .* d = dz / N"):
        Optics(0.3, 3.0, defocus_blur_diameter_m=bad)
    with pytest.raises(SatsightError, match="blur_diameter_m"):
        defocus_mtf(1e4, bad)


# --- camera equation --------------------------------------------------------------------------


def test_irradiance_closed_form():
    radiance = np.full((4, 5), 12.5)
    e = focal_plane_irradiance_w_m2(radiance, OPTICS)
    expected = math.pi * 12.5 * 0.8 / (4 * N**2)
    np.testing.assert_allclose(e, expected, rtol=REL)
    obscured = Optics(0.3, 3.0, obscuration_ratio=0.4)
    np.testing.assert_allclose(
        focal_plane_irradiance_w_m2(radiance, obscured), expected * (1 - 0.16), rtol=REL
    )
    theta = np.full((4, 5), 0.3)
    np.testing.assert_allclose(
        focal_plane_irradiance_w_m2(radiance, OPTICS, theta),
        expected * math.cos(0.3) ** 4,
        rtol=REL,
    )
    assert focal_plane_irradiance_w_m2(radiance.astype(np.float32), OPTICS).dtype == np.float32
    with pytest.raises(SatsightError):
        focal_plane_irradiance_w_m2(radiance, OPTICS, np.full((4, 5), 2.0))


# --- MTF ---------------------------------------------------------------------------------------


def test_diffraction_mtf_clear_closed_form_and_cutoff():
    x = np.linspace(0.0, 1.0, 2001)[:-1]
    mtf = diffraction_mtf(x * CUTOFF_CYC_PER_M, LAM_M, N)
    np.testing.assert_allclose(mtf, clear_mtf_closed_form(x), rtol=0, atol=REL)
    assert diffraction_mtf(0.0, LAM_M, N) == 1.0
    # At the cut-off x = 1 up to rounding; the MTF goes as (1 - x)^(3/2) there, so 1e-12 is
    # far above what a 1e-16 error in x can produce.
    assert diffraction_mtf(CUTOFF_CYC_PER_M, LAM_M, N) == pytest.approx(0.0, abs=1e-12)
    beyond = diffraction_mtf(CUTOFF_CYC_PER_M * np.array([1.0001, 1.5, 10.0]), LAM_M, N)
    np.testing.assert_array_equal(beyond, 0.0)
    # D / (lambda f) is the same cut-off.
    assert diffraction_mtf(0.3 / (LAM_M * 3.0) * 1.000001, LAM_M, N) == 0.0


def test_annular_mtf_matches_oneill_closed_form():
    nu = np.linspace(0.0, 0.999, 1999)
    for eps in (0.3, 0.5, 0.7):
        got = diffraction_mtf(nu * CUTOFF_CYC_PER_M, LAM_M, N, eps)
        # arccos near +-1 in O'Neill's phi amplifies float64 rounding as 1/sqrt(1 - c^2):
        # 1e-7 is a generous bound for that amplification on this grid.
        np.testing.assert_allclose(got, oneill_annular_mtf(nu, eps), rtol=0, atol=1e-7)


def test_annular_mtf_matches_pupil_autocorrelation():
    # Pixelised annular pupil of radius 200 samples, autocorrelated by FFT: edge pixelisation
    # errors are of order 1 / R = 5e-3 per edge crossing, averaging down; 1e-3 bounds them.
    radius, eps = 200, 0.5
    n = 4 * radius + 8
    y, x = np.indices((n, n)) - n // 2 + 0.5
    r = np.hypot(x, y)
    pupil = ((r <= radius) & (r >= eps * radius)).astype(float)
    spectrum = np.fft.fft2(pupil)
    ac = np.real(np.fft.ifft2(np.abs(spectrum) ** 2))
    ac /= ac[0, 0]
    shift = np.arange(2 * radius)
    nu = shift / (2 * radius)  # a shift of the pupil diameter is the cut-off
    np.testing.assert_allclose(
        ac[0, shift], diffraction_mtf(nu * CUTOFF_CYC_PER_M, LAM_M, N, eps), atol=1e-3
    )


def test_annular_mtf_limits_and_classic_shape():
    f = np.linspace(0.0, 1.2, 241) * CUTOFF_CYC_PER_M
    clear = diffraction_mtf(f, LAM_M, N)
    np.testing.assert_allclose(diffraction_mtf(f, LAM_M, N, 0.0), clear, rtol=0, atol=0)
    np.testing.assert_allclose(diffraction_mtf(f, LAM_M, N, 1e-9), clear, atol=1e-12)
    annular = diffraction_mtf(f, LAM_M, N, 0.5)
    assert annular[0] == pytest.approx(1.0, abs=1e-15)
    assert np.all(annular[f >= CUTOFF_CYC_PER_M] == 0.0)
    assert np.all(annular[(f > 0) & (f < CUTOFF_CYC_PER_M)] > 0.0)
    x = f / CUTOFF_CYC_PER_M
    assert np.all(annular[(x > 0.02) & (x <= 0.5)] < clear[(x > 0.02) & (x <= 0.5)])
    assert np.all(annular[(x >= 0.75) & (x < 1.0)] > clear[(x >= 0.75) & (x < 1.0)])


def test_pixel_and_jitter_mtf():
    p = 15e-6
    assert pixel_mtf(1.0 / p, p) == pytest.approx(0.0, abs=1e-15)
    assert pixel_mtf(0.0, p) == 1.0
    assert pixel_mtf(1.0 / (2 * p), p) == pytest.approx(2 / math.pi, rel=REL)
    sigma_rad, f_m = 2e-6, 3.0
    f_half = 1.0 / (2 * math.pi * sigma_rad * f_m)
    assert jitter_mtf(f_half, sigma_rad, f_m) == pytest.approx(math.exp(-0.5), rel=REL)
    assert jitter_mtf(1e5, 0.0, f_m) == 1.0


def test_system_mtf_is_band_averaged_product():
    optics = Optics(0.3, 3.0, jitter_rms_rad=1e-6)
    p = 15e-6
    f = np.linspace(0.0, 1.0 / (2 * p), 50)
    lam = band_wavelengths_m((450.0, 900.0), 16)
    assert lam[0] == pytest.approx(464.0625e-9, rel=REL)
    assert lam[-1] == pytest.approx(885.9375e-9, rel=REL)
    diff = np.mean([diffraction_mtf(f, lk, 10.0) for lk in lam], axis=0)
    expected = diff * pixel_mtf(f, p) * jitter_mtf(f, 1e-6, 3.0)
    np.testing.assert_allclose(system_mtf(f, optics, p), expected, rtol=REL, atol=1e-15)
    # explicit weights: all weight on one wavelength
    w = np.zeros(16)
    w[3] = 2.0
    one = diffraction_mtf(f, lam[3], 10.0) * pixel_mtf(f, p) * jitter_mtf(f, 1e-6, 3.0)
    np.testing.assert_allclose(system_mtf(f, optics, p, lam, w), one, rtol=REL, atol=1e-15)


DEFOCUS_D_M = 90e-6  # blur-circle diameter: 6 pixels of 15 um


def test_defocus_mtf_is_the_pillbox_transform_with_its_first_zero_and_negative_lobe():
    d = DEFOCUS_D_M
    first_zero = FIRST_ZERO_V / (math.pi * d)
    assert defocus_mtf(0.0, d) == 1.0
    assert defocus_mtf(first_zero, d) == pytest.approx(0.0, abs=1e-15)
    assert defocus_mtf(0.999 * first_zero, d) > 0.0 > defocus_mtf(1.001 * first_zero, d)
    np.testing.assert_array_equal(defocus_mtf(np.linspace(0.0, 1e6, 7), 0.0), 1.0)
    # Signed OTF: the first negative lobe of 2 J1(u) / u reaches -0.1323 at u = 5.1356.
    u = np.linspace(0.0, 20.0, 20001)
    otf = defocus_mtf(u / (math.pi * d), d)
    assert otf.min() == pytest.approx(-0.132279, abs=1e-6)
    assert u[np.argmin(otf)] == pytest.approx(5.1356, abs=1e-3)
    np.testing.assert_array_equal(defocus_mtf(-u / (math.pi * d), d), otf)  # even in f
    # Independent oracle: the Hankel transform of the uniform disc of radius a = d / 2,
    # OTF(f) = (2 / a^2) int_0^a J0(2 pi f r) r dr, by quadrature.
    a = d / 2
    for f in (0.3 * first_zero, first_zero, 1.7 * first_zero, 4.2 * first_zero):
        hankel = integrate.quad(lambda r, f=f: j0(2 * math.pi * f * r) * r, 0.0, a, limit=200)[0]
        assert defocus_mtf(f, d) == pytest.approx(2 * hankel / a**2, abs=1e-12)


def test_system_mtf_includes_signed_defocus_and_d0_is_unchanged():
    p = 15e-6
    f = np.linspace(0.0, 1.0 / (2 * p), 50)
    sharp = Optics(0.3, 3.0, jitter_rms_rad=1e-6)
    lam = band_wavelengths_m()
    diff = sum(diffraction_mtf(f, lk, 10.0) / lam.size for lk in lam)
    product = diff * pixel_mtf(f, p) * jitter_mtf(f, 1e-6, 3.0)
    zero = Optics(0.3, 3.0, jitter_rms_rad=1e-6, defocus_blur_diameter_m=0.0)
    np.testing.assert_array_equal(system_mtf(f, zero, p), system_mtf(f, sharp, p))
    np.testing.assert_array_equal(system_mtf(f, sharp, p), product)
    blurred = Optics(0.3, 3.0, jitter_rms_rad=1e-6, defocus_blur_diameter_m=DEFOCUS_D_M)
    got = system_mtf(f, blurred, p)
    np.testing.assert_allclose(got, product * defocus_mtf(f, DEFOCUS_D_M), rtol=REL, atol=1e-15)
    assert got.min() < -0.01  # the sign survives: frequencies past 3.83 / (pi d) reverse


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
    with pytest.raises(SatsightError):
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


# --- apply_optics ------------------------------------------------------------------------------


def _small_psf(size: int = 9) -> np.ndarray:
    return psf_kernel(OPTICS, band_wavelengths_m(None, 4), None, 5e-6, size)


def test_apply_optics_conserves_power_and_flat_field():
    s = 2
    psf = _small_psf(9)
    img = np.zeros((64 * s, 80 * s))
    img[40:90, 50:120] = 3.0  # a uniform patch well inside the borders
    out = apply_optics(img, psf, s)
    assert out.shape == (64, 80)
    pixel_area, sample_area = 1.0, 1.0 / s**2  # relative areas
    assert out.sum() * pixel_area == pytest.approx(img.sum() * sample_area, rel=1e-6)
    # interior of the patch, farther than the kernel radius from its edges: unchanged
    interior = out[(40 + 4) // s + 1 : (90 - 4) // s - 1, (50 + 4) // s + 1 : (120 - 4) // s - 1]
    np.testing.assert_allclose(interior, 3.0, rtol=1e-12)


def test_apply_optics_fast_path_equals_full_convolution():
    rng = np.random.default_rng(7)
    s = 3
    psf = _small_psf(11)
    img = np.zeros((40 * s, 50 * s))
    y, x = np.indices(img.shape)
    blob = np.hypot(y - 50, x - 70) < 12
    img[blob] = rng.uniform(1.0, 2.0, blob.sum())
    img[2, 3] = 5.0  # near a corner: its blur is cut by the frame in both paths
    full = fftconvolve(img, psf, mode="same")
    full = np.maximum(full, 0).reshape(40, s, 50, s).mean(axis=(1, 3))
    fast = apply_optics(img, psf, s)
    np.testing.assert_allclose(fast, full, rtol=1e-6, atol=1e-6 * full.max())


def test_apply_optics_empty_frame_and_point_source():
    psf = _small_psf(9)
    out = apply_optics(np.zeros((30, 40), dtype=np.float32), psf, 1)
    assert out.dtype == np.float32
    assert not out.any()
    s = 3
    img = np.zeros((20 * s, 20 * s))
    img[10 * s + 1, 10 * s + 1] = 1.0  # centre sample of pixel (10, 10)
    out = apply_optics(img, psf, s)
    padded = np.zeros((21 * s, 21 * s))
    c = 10 * s + 1
    padded[c - 4 : c + 5, c - 4 : c + 5] = psf
    expected = padded[: 20 * s, : 20 * s].reshape(20, s, 20, s).mean(axis=(1, 3))
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-15)
    assert out.sum() == pytest.approx(1.0 / s**2, rel=1e-9)


def test_apply_optics_rejects_bad_input():
    psf = _small_psf(9)
    with pytest.raises(SatsightError):
        apply_optics(np.zeros((31, 40)), psf, 2)
    with pytest.raises(SatsightError):
        apply_optics(np.zeros((30, 40)), np.ones((4, 4)) / 16, 1)
    with pytest.raises(SatsightError):
        apply_optics(np.zeros((30, 40, 3)), psf, 1)


# --- plot --------------------------------------------------------------------------------------


def test_plot_system_mtf_writes_png(tmp_path):
    optics = Optics.for_preset("high_resolution", jitter_rms_rad=1e-6)
    path = plot_system_mtf(optics, 15e-6, (450.0, 900.0), tmp_path / "mtf" / "system.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 10_000
    defocused = Optics.for_preset("high_resolution", defocus_blur_diameter_m=DEFOCUS_D_M)
    path = plot_system_mtf(defocused, 15e-6, (450.0, 900.0), tmp_path / "defocus.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _textured_scene(shape: tuple[int, int], dtype: type) -> np.ndarray:
    """A textured extended target, a few point sources and empty space around them."""
    rng = np.random.default_rng(11)
    img = np.zeros(shape, dtype=dtype)
    h, w = shape
    img[h // 5 : 3 * h // 4, w // 6 : w // 2] = rng.uniform(
        0.1, 1.0, (3 * h // 4 - h // 5, w // 2 - w // 6)
    )
    img[rng.integers(0, h, 20), rng.integers(0, w, 20)] = 5.0
    img[h - 1, w - 1] = 2.0  # in the corner: the blur is cut by the frame
    return img


@pytest.mark.parametrize("s", [1, 2])
def test_apply_optics_float32_matches_fftconvolve_for_any_thread_count(s):
    # 900 x 1500 samples: several row and column bands of the banded FFT. The reference is
    # scipy's fftconvolve of the whole frame in float32; the two differ by FFT round-off
    # (~1e-7 relative per term, a few e-7 of the peak after ~20 butterfly levels).
    psf = psf_kernel(OPTICS, band_wavelengths_m(None, 4), None, 5e-6 / s, 15)
    img = _textured_scene((900, 1500), np.float32)
    ref = fftconvolve(img, psf.astype(np.float32), mode="same")
    ref = np.maximum(ref, 0).reshape(900 // s, s, 1500 // s, s).mean(axis=(1, 3))
    outs = [apply_optics(img, psf, s, threads=k) for k in (1, 2, 3)]
    assert outs[0].dtype == np.float32
    np.testing.assert_allclose(outs[0], ref, rtol=0, atol=4e-6 * float(ref.max()))
    assert outs[1].tobytes() == outs[0].tobytes()
    assert outs[2].tobytes() == outs[0].tobytes()


def test_fft_convolve_same_matches_direct_convolution():
    # Float64 against scipy's direct (non-FFT) convolution: non-symmetric kernels, an image
    # split into several bands, and a kernel larger than the image.
    rng = np.random.default_rng(12)
    img = rng.uniform(0.0, 1.0, (700, 1500))
    kern = rng.uniform(0.0, 1.0, (15, 9))
    direct = convolve2d(img, kern, mode="same")
    np.testing.assert_allclose(fft_convolve_same(img, kern, threads=2), direct, rtol=1e-10)
    small = rng.uniform(0.0, 1.0, (5, 7))
    big_kernel = rng.uniform(0.0, 1.0, (15, 11))
    np.testing.assert_allclose(
        fft_convolve_same(small, big_kernel),
        fftconvolve(small, big_kernel, mode="same"),
        rtol=1e-10,
    )
    np.testing.assert_allclose(
        fft_convolve_same(small, big_kernel),
        convolve2d(small, big_kernel, mode="same"),
        rtol=1e-10,
    )


def test_apply_optics_with_a_known_signal_box_equals_the_scanned_result() -> None:
    psf = psf_kernel(Optics.for_preset("high_resolution"), band_wavelengths_m(), None, 15e-6, 15)
    image = np.zeros((60, 70), np.float32)
    image[20:31, 25:41] = np.random.default_rng(3).uniform(0.1, 1.0, (11, 16))
    scanned = apply_optics(image, psf)
    boxed = apply_optics(image, psf, signal_box=(20, 31, 25, 41))
    np.testing.assert_array_equal(boxed, scanned)
    # A larger box (still holding all the signal) gives the same image to round-off.
    np.testing.assert_allclose(
        apply_optics(image, psf, signal_box=(5, 50, 10, 60)), scanned, atol=1e-6 * scanned.max()
    )
    with pytest.raises(SatsightError, match="signal_box"):
        apply_optics(image, psf, signal_box=(30, 20, 0, 10))
