"""MTF components: diffraction (clear and annular pupil), pixel, jitter, defocus, the system
MTF and 2-D OTF, and the renderer's sub-pixel sampling response.

Oracles: closed forms (Goodman Sec. 6.4 clear-pupil OTF; O'Neill 1956 annular OTF; the
pillbox's Hankel transform by quadrature) and an FFT autocorrelation of a pixelised pupil.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.special import j0

from satsight.errors import SatsightError
from satsight.sensor.mtf import (
    band_wavelengths_m,
    defocus_mtf,
    diffraction_mtf,
    jitter_mtf,
    pixel_mtf,
    render_sampling_otf,
    system_mtf,
    system_otf_2d,
)
from satsight.sensor.optics import Optics

REL = 1e-12  # closed forms evaluated the same way up to float64 rounding
LAM_M = 550e-9
N = 10.0
OPTICS = Optics(aperture_diameter_m=0.3, focal_length_m=3.0)  # f/10
CUTOFF_CYC_PER_M = 1.0 / (LAM_M * N)
FIRST_ZERO_V = 3.8317059702075125  # first zero of J1


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


# --- 2-D OTF and the renderer's sampling -------------------------------------------------------

PITCH_M = 15e-6
NYQUIST_CYC_PER_M = 1.0 / (2 * PITCH_M)


@pytest.mark.parametrize(
    "optics",
    [
        Optics.for_preset("wide_field"),
        Optics(0.3, 3.0, obscuration_ratio=0.35, jitter_rms_rad=1e-6),
        Optics(0.3, 3.0, defocus_blur_diameter_m=DEFOCUS_D_M),
    ],
    ids=["wide_field", "obscured_jitter", "defocus"],
)
def test_system_otf_2d_is_the_system_mtf_along_either_axis_and_radial_off_it(optics):
    f = np.linspace(0.0, 0.99 / PITCH_M, 200)  # below the pixel sinc's first zero
    along_x = system_otf_2d(f, 0.0, optics, PITCH_M)
    np.testing.assert_allclose(along_x, system_mtf(f, optics, PITCH_M), rtol=REL, atol=1e-15)
    np.testing.assert_array_equal(system_otf_2d(0.0, f, optics, PITCH_M), along_x)
    np.testing.assert_array_equal(system_otf_2d(-f, 0.0, optics, PITCH_M), along_x)
    # Off the axes: H / (sinc(p fx) sinc(p fy)) depends on |f| only (diffraction, jitter and
    # defocus are radial), the closed form of the independent radial factors.
    angle = 0.6
    fx, fy = f * math.cos(angle), f * math.sin(angle)
    radial = system_mtf(f, optics, PITCH_M) / pixel_mtf(f, PITCH_M)
    got = system_otf_2d(fx, fy, optics, PITCH_M) / (np.sinc(PITCH_M * fx) * np.sinc(PITCH_M * fy))
    np.testing.assert_allclose(got[1:], radial[1:], rtol=1e-10, atol=1e-14)


def test_render_sampling_otf_closed_forms():
    f = np.linspace(-NYQUIST_CYC_PER_M, 3 * NYQUIST_CYC_PER_M, 301)
    u = f * PITCH_M  # cycles per pixel
    np.testing.assert_array_equal(render_sampling_otf(f, PITCH_M), 1.0)  # one centre sample
    # Two stratum centres at +-p/4: cos(pi u / 2).
    np.testing.assert_allclose(
        render_sampling_otf(f, PITCH_M, 2), np.cos(math.pi * u / 2), rtol=0, atol=1e-15
    )
    for s in range(3, 9):  # s equally spaced centres: the Dirichlet kernel
        expected = np.where(
            u == 0, 1.0, np.sin(math.pi * u) / (s * np.sin(math.pi * u / s) + (u == 0))
        )
        np.testing.assert_allclose(render_sampling_otf(f, PITCH_M, s), expected, rtol=0, atol=1e-14)
    # Positions spread uniformly over the pixel: the box, whatever the strata.
    for s, spp in ((1, 2), (3, 16)):
        np.testing.assert_allclose(
            render_sampling_otf(f, PITCH_M, s, spp), np.sinc(u), rtol=0, atol=1e-15
        )
    # Within the Nyquist band the response stays in [2 / pi, 1]: the kernel can divide by it.
    band = np.linspace(0.0, NYQUIST_CYC_PER_M, 101)
    for s, spp in ((1, 1), (2, 1), (8, 1), (1, 4)):
        response = render_sampling_otf(band, PITCH_M, s, spp)
        assert response.min() >= 2 / math.pi - 1e-12
        assert response.max() <= 1.0


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_render_sampling_otf_rejects_bad_sampling(bad):
    with pytest.raises(SatsightError, match="supersampling"):
        render_sampling_otf(1e4, PITCH_M, bad, 1)
    with pytest.raises(SatsightError, match="samples_per_pixel"):
        render_sampling_otf(1e4, PITCH_M, 1, bad)
