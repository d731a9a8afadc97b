"""The band QE weighted by the light's spectrum, against independent integrals."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.sensor.band_qe import blackbody_weighted_qe, solar_weighted_qe

H_C_OVER_K_M_K = 6.62607015e-34 * 299_792_458.0 / 1.380649e-23


def _table(package: str, name: str) -> np.ndarray:
    text = (resources.files(package) / "data" / name).read_text(encoding="utf-8")
    rows = [s for s in text.splitlines() if s.strip() and not s.startswith("#")][1:]
    return np.array([[float(v) for v in s.split(",")] for s in rows])


def test_solar_weighted_qe_is_the_photon_weighted_mean_of_the_curve():
    # Independent: E-490 (W m^-2 nm^-1) times lambda (photons), times the QE table, both
    # read from the data files, trapezoid on the E-490 grid (1 nm here, the QE table 50 nm
    # apart and linear between samples, so the grid holds its kinks to within 1 nm: the two
    # sums differ by far less than 1e-4).
    e490 = _table("satsight.lighting", "astm_e490_am0.csv")
    qe = _table("satsight.camera", "ccd231_84_astro_multi2_qe.csv")
    inside = (e490[:, 0] >= 450.0) & (e490[:, 0] <= 900.0)
    wl, e = e490[inside, 0], e490[inside, 1]
    photons = e * wl
    expected = np.trapezoid(photons * np.interp(wl, qe[:, 0], qe[:, 1]), wl) / np.trapezoid(
        photons, wl
    )
    assert solar_weighted_qe((450.0, 900.0)) == pytest.approx(expected, abs=1e-4)
    assert 0.80 < expected < 0.83  # the scalar 0.9 it replaces was 11 % high


def test_a_stars_qe_follows_its_own_spectrum():
    # Independent: Planck's law on a 0.5 nm grid, trapezoid. Hot stars put more of their
    # photons where the curve is high (blue), cool ones towards 900 nm where it falls.
    qe = _table("satsight.camera", "ccd231_84_astro_multi2_qe.csv")
    wl = np.linspace(450.0, 900.0, 901)
    temps = np.array([3500.0, 5772.0, 10000.0])
    planck = wl[None, :] ** -5 / np.expm1(H_C_OVER_K_M_K / (wl[None, :] * 1e-9 * temps[:, None]))
    photons = planck * wl[None, :]
    curve = np.interp(wl, qe[:, 0], qe[:, 1])
    expected = np.trapezoid(photons * curve, wl, axis=1) / np.trapezoid(photons, wl, axis=1)
    got = blackbody_weighted_qe((450.0, 900.0), temps)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-4)
    assert got[0] < got[1] < got[2]
    with pytest.raises(SatsightError, match="temperature_k"):
        blackbody_weighted_qe((450.0, 900.0), np.array([-1.0]))
