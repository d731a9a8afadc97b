"""Band integration: channel reflectance against independent trapezoid sums on the raw
E-490 table, flat spectra, and the QE curves."""

from __future__ import annotations

import numpy as np
import pytest

from satsight.camera.quantum_efficiency import load_quantum_efficiency
from satsight.lighting.solar_spectrum import load_e490
from satsight.scene.band_reflectance import (
    band_mean,
    base_colour_from_reflectance,
    channel_edges_nm,
    channel_reflectance,
)

# Both sides integrate the same piecewise-linear functions; they differ only in where the
# nodes lie inside 1 nm E-490 intervals (the reference uses the raw table alone), so they
# agree to about 1e-4 of the mean.
HAND_TOL = 2e-4


def _raw_e490_nm():
    wl_m, e = load_e490()
    return wl_m * 1e9, e * 1e-9


def _hand_mean(rho, lo, hi):
    """Independent photon-weighted mean: trapezoid on the raw E-490 samples inside the band."""
    wl, e = _raw_e490_nm()
    sel = (wl > lo) & (wl < hi)
    x = np.concatenate(([lo], wl[sel], [hi]))
    w = np.interp(x, wl, e) * x
    return np.trapezoid(w * rho(x), x) / np.trapezoid(w, x)


def test_thirds_of_the_default_band() -> None:
    np.testing.assert_allclose(channel_edges_nm((450, 900)), [450, 600, 750, 900])


def test_flat_spectrum_gives_equal_channels() -> None:
    wl = np.array([400.0, 1800.0])
    for qe in ("flat", "ccd231_84"):
        r, g, b = channel_reflectance(wl, np.array([0.37, 0.37]), (450, 900), qe)
        assert r == pytest.approx(0.37, abs=1e-12)
        assert g == pytest.approx(0.37, abs=1e-12) and b == pytest.approx(0.37, abs=1e-12)


def test_step_spectrum_against_a_hand_integration() -> None:
    """rho = 0.2 below 520 nm, 0.8 above (a step inside the blue third, 450-600 nm)."""
    wl = np.array([400.0, 519.999, 520.001, 1800.0])
    refl = np.array([0.2, 0.2, 0.8, 0.8])
    got = band_mean(wl, refl, 450.0, 600.0, "flat")
    expected = _hand_mean(lambda x: np.where(x < 520.0, 0.2, 0.8), 450.0, 600.0)
    assert got == pytest.approx(expected, abs=HAND_TOL)


def test_linear_spectrum_against_a_hand_integration() -> None:
    wl = np.array([400.0, 1800.0])
    refl = np.array([0.1, 0.9])

    def rho(x):
        return 0.1 + 0.8 * (x - 400.0) / 1400.0

    r, g, b = channel_reflectance(wl, refl, (450, 900), "flat")
    for got, (lo, hi) in zip((b, g, r), [(450, 600), (600, 750), (750, 900)], strict=True):
        assert got == pytest.approx(_hand_mean(rho, lo, hi), abs=HAND_TOL)
    assert r > g > b  # a rising spectrum is red


def test_qe_weighting_shifts_the_mean_towards_where_the_detector_sees() -> None:
    """The CCD's QE falls from 750 to 900 nm, so in the red third a rising spectrum's
    QE-weighted mean is lower than its photon-weighted mean."""
    wl = np.array([400.0, 1800.0])
    refl = np.array([0.0, 1.0])
    flat = band_mean(wl, refl, 750, 900, "flat")
    ccd = band_mean(wl, refl, 750, 900, "ccd231_84")
    assert ccd < flat


def test_qe_curve_is_in_range_and_zero_beyond_the_band_gap() -> None:
    qe = load_quantum_efficiency("ccd231_84")
    assert np.all((qe.qe >= 0) & (qe.qe <= 1))
    assert qe(np.array([1200.0]))[0] == 0.0  # silicon band gap: 1107 nm
    assert load_quantum_efficiency("flat")(np.array([300.0, 2000.0])).tolist() == [1.0, 1.0]


def test_base_colour_of_a_metal_is_its_reflectance() -> None:
    assert base_colour_from_reflectance((0.9, 0.5, 0.1), 1.0, 1.5) == pytest.approx((0.9, 0.5, 0.1))


def test_base_colour_of_a_dielectric_removes_the_interface() -> None:
    """An ideal Lambertian (IOR 1, no interface) keeps its reflectance as albedo; with an
    interface the albedo is larger than the measured total reflectance minus F0."""
    assert base_colour_from_reflectance((0.5, 0.5, 0.5), 0.0, 1.0) == pytest.approx((0.5,) * 3)
    f0 = 0.04
    r = base_colour_from_reflectance((0.5, 0.5, 0.5), 0.0, 1.5)[0]
    assert r > 0.5 - f0
