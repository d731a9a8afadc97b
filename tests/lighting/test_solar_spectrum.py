"""The solar spectrum: the ASTM E-490 table, the scaled black body, in-band irradiance.

Reference values:
* ASTM E-490-00a: solar constant 1366.1 W m^-2 (the standard's published value).
* In-band 450-900 nm at 1 AU: 671.5 W m^-2 from E-490, the value satsight's scenarios use
  by default; the paper quotes 647.7 W m^-2 for a 5778 K black body scaled to the solar
  constant.
The tests recompute every integral independently: the E-490 band by scipy's trapezoid on a
fine interpolated grid, the black body by scipy's adaptive quad on Planck's law.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from scipy import constants
from scipy.integrate import quad, trapezoid

from satsight.errors import SatsightError
from satsight.lighting import solar_spectrum as ss

E490_SOLAR_CONSTANT_W_M2 = 1366.1  # ASTM E-490-00a
E490_SOLAR_CONSTANT_TOL_W_M2 = 0.5
SCENARIO_DEFAULT_IRRADIANCE_W_M2 = 671.5  # 450-900 nm, E-490, 1 AU
PAPER_BLACKBODY_BAND_W_M2 = 647.7  # the paper's 450-900 nm irradiance, 5778 K black body
HALF_PERCENT = 5e-3
REL_QUADRATURE = 1e-9  # two accurate quadratures of the same smooth integral
NM = 1e-9


def _planck_exitance(wavelength_m: float, temperature_k: float) -> float:
    """pi B_lambda(T) = 2 pi h c^2 / lambda^5 / (exp(h c / (lambda k T)) - 1), W m^-2 m^-1."""
    h, c, k = constants.h, constants.c, constants.k
    x = h * c / (wavelength_m * k * temperature_k)
    return 2.0 * math.pi * h * c**2 / wavelength_m**5 / math.expm1(x)


def _blackbody_band_fraction(lo_nm: float, hi_nm: float, temperature_k: float) -> float:
    band, _ = quad(
        _planck_exitance, lo_nm * NM, hi_nm * NM, args=(temperature_k,), epsabs=0, epsrel=1e-12
    )
    return band / (constants.Stefan_Boltzmann * temperature_k**4)


def _e490_band_fine_grid(lo_nm: float, hi_nm: float, step_nm: float = 0.01) -> float:
    """In-band E-490 irradiance, W m^-2: linear interpolation onto a fine grid, trapezoid."""
    wavelength_m, irradiance = ss.load_e490()
    grid_m = np.linspace(lo_nm, hi_nm, round((hi_nm - lo_nm) / step_nm) + 1) * NM
    return float(trapezoid(np.interp(grid_m, wavelength_m, irradiance), grid_m))


def test_table_is_in_si_units_and_complete() -> None:
    wavelength_m, irradiance = ss.load_e490()
    assert wavelength_m.shape == irradiance.shape == (1697,)
    assert wavelength_m.dtype == irradiance.dtype == np.float64
    assert np.all(np.diff(wavelength_m) > 0)
    assert wavelength_m[0] == pytest.approx(119.5e-9, rel=1e-12)
    assert wavelength_m[-1] == pytest.approx(1e-3, rel=1e-12)
    assert np.all(irradiance >= 0)
    # The visible peak is near 1.9-2.1 W m^-2 nm^-1 = 1.9e9-2.1e9 W m^-2 m^-1 at 450-500 nm.
    peak = wavelength_m[np.argmax(irradiance)]
    assert 400e-9 < peak < 500e-9
    assert 1.9e9 < irradiance.max() < 2.3e9
    assert not wavelength_m.flags.writeable


def test_solar_constant_is_the_published_e490_value() -> None:
    total = ss.solar_constant_w_m2()
    assert abs(total - E490_SOLAR_CONSTANT_W_M2) <= E490_SOLAR_CONSTANT_TOL_W_M2
    # The same integral by scipy's trapezoid on the table itself.
    wavelength_m, irradiance = ss.load_e490()
    assert total == pytest.approx(float(trapezoid(irradiance, wavelength_m)), rel=1e-12)


def test_e490_band_matches_an_independent_integration() -> None:
    band = ss.band_irradiance_w_m2((450.0, 900.0), "astm_e490")
    assert band == pytest.approx(_e490_band_fine_grid(450.0, 900.0), rel=1e-6)
    assert band == pytest.approx(SCENARIO_DEFAULT_IRRADIANCE_W_M2, rel=HALF_PERCENT)
    assert ss.band_irradiance_w_m2() == band  # the defaults are the paper's band and E-490


@pytest.mark.parametrize(("lo_nm", "hi_nm"), [(450.3, 450.7), (500.25, 777.7), (1500.0, 2500.0)])
def test_e490_band_edges_between_samples_are_exact(lo_nm: float, hi_nm: float) -> None:
    assert ss.band_irradiance_w_m2((lo_nm, hi_nm)) == pytest.approx(
        _e490_band_fine_grid(lo_nm, hi_nm, step_nm=0.001), rel=1e-7
    )


def test_e490_bands_add_up() -> None:
    whole = ss.band_irradiance_w_m2((450.0, 900.0))
    parts = ss.band_irradiance_w_m2((450.0, 633.3)) + ss.band_irradiance_w_m2((633.3, 900.0))
    assert parts == pytest.approx(whole, rel=1e-13)
    table_span = (119.5, 1.0e6)
    assert ss.band_irradiance_w_m2(table_span) == pytest.approx(ss.solar_constant_w_m2(), 1e-12)


def test_blackbody_band_matches_planck_integrated_by_quad() -> None:
    band = ss.band_irradiance_w_m2((450.0, 900.0), "blackbody_5778k")
    expected = E490_SOLAR_CONSTANT_W_M2 * _blackbody_band_fraction(450.0, 900.0, 5778.0)
    assert band == pytest.approx(expected, rel=REL_QUADRATURE)
    assert band == pytest.approx(648.7, rel=HALF_PERCENT)
    assert band == pytest.approx(PAPER_BLACKBODY_BAND_W_M2, rel=HALF_PERCENT)


def test_blackbody_parameters() -> None:
    # IAU 2015 nominal solar effective temperature, and another total.
    band = ss.band_irradiance_w_m2(
        (450.0, 900.0), "blackbody_5778k", temperature_k=5772.0, total_w_m2=1361.0
    )
    expected = 1361.0 * _blackbody_band_fraction(450.0, 900.0, 5772.0)
    assert band == pytest.approx(expected, rel=REL_QUADRATURE)
    # The whole spectrum holds the total (sigma T^4 scaled to total_w_m2).
    everything = ss.band_irradiance_w_m2((1.0, 1.0e9), "blackbody_5778k")
    assert everything == pytest.approx(E490_SOLAR_CONSTANT_W_M2, rel=1e-9)


@pytest.mark.parametrize("spectrum", ss.SPECTRA)
@pytest.mark.parametrize("distance_au", [0.3871, 0.983, 1.017, 5.2])
def test_inverse_square_distance(spectrum: str, distance_au: float) -> None:
    at_1au = ss.band_irradiance_w_m2((450.0, 900.0), spectrum)
    at_d = ss.band_irradiance_w_m2((450.0, 900.0), spectrum, distance_au=distance_au)
    assert at_d == pytest.approx(at_1au / distance_au**2, rel=1e-14)


def test_spectral_weights_are_band_fractions() -> None:
    edges = (450.0, 550.0, 700.0, 900.0)
    weights = ss.spectral_weights(edges)
    assert weights.shape == (3,)
    assert float(np.sum(weights)) == pytest.approx(1.0, abs=1e-14)
    total = _e490_band_fine_grid(450.0, 900.0)
    for k in range(3):
        part = _e490_band_fine_grid(edges[k], edges[k + 1])
        assert weights[k] == pytest.approx(part / total, rel=1e-6)
    bb = ss.spectral_weights(edges, "blackbody_5778k")
    bb_total = _blackbody_band_fraction(450.0, 900.0, 5778.0)
    expected = [_blackbody_band_fraction(lo, hi, 5778.0) / bb_total for lo, hi in ((450, 550),)]
    assert bb[0] == pytest.approx(expected[0], rel=REL_QUADRATURE)


@pytest.mark.parametrize(
    ("band_nm", "spectrum", "message"),
    [
        ((900.0, 450.0), "astm_e490", "lo < hi"),
        ((450.0, 450.0), "astm_e490", "lo < hi"),
        ((-10.0, 450.0), "blackbody_5778k", "lo < hi"),
        ((100.0, 900.0), "astm_e490", "outside the ASTM E-490 table"),
        ((450.0, 2.0e6), "astm_e490", "outside the ASTM E-490 table"),
        ((450.0, float("nan")), "astm_e490", "lo < hi"),
        ((450.0, 900.0), "kurucz", "unknown spectrum"),
    ],
)
def test_bad_bands_are_refused(band_nm: tuple[float, float], spectrum: str, message: str) -> None:
    with pytest.raises(SatsightError, match=message):
        ss.band_irradiance_w_m2(band_nm, spectrum)  # type: ignore[arg-type]


@pytest.mark.parametrize("distance_au", [0.0, -1.0, float("inf")])
def test_bad_distance_is_refused(distance_au: float) -> None:
    with pytest.raises(SatsightError, match="distance_au"):
        ss.band_irradiance_w_m2(distance_au=distance_au)


def test_bad_spectral_weight_edges_are_refused() -> None:
    with pytest.raises(SatsightError, match="increasing"):
        ss.spectral_weights((450.0, 700.0, 600.0))
    with pytest.raises(SatsightError, match="at least two"):
        ss.spectral_weights((450.0,))


def test_damaged_data_file_is_detected(tmp_path) -> None:
    good = tmp_path / "good.csv"
    shutil.copyfile(ss.e490_path(), good)
    assert ss._read_verified(good).startswith("#")
    # Windows line endings are the same data.
    crlf = tmp_path / "crlf.csv"
    crlf.write_bytes(good.read_bytes().replace(b"\n", b"\r\n"))
    assert ss._read_verified(crlf) == ss._read_verified(good)
    damaged = tmp_path / "damaged.csv"
    damaged.write_bytes(good.read_bytes().replace(b"550.5,", b"550.6,", 1))
    with pytest.raises(SatsightError, match="damaged"):
        ss._read_verified(damaged)
    with pytest.raises(SatsightError, match="cannot be read"):
        ss._read_verified(tmp_path / "missing.csv")


def test_data_file_header_names_source_and_units() -> None:
    text = ss._read_verified(ss.e490_path())
    header = [line for line in text.splitlines() if line.startswith("#")]
    joined = " ".join(header)
    assert "E-490" in joined and "nrel.gov" in joined
    assert "wavelength_nm,spectral_irradiance_w_m2_nm" in text.splitlines()
