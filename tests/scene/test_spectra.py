"""Reflectance from optical constants: metals against published values, closed forms of
thin-film optics (bulk dielectric, zero-thickness film, quarter-wave AR layer)."""

from __future__ import annotations

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.scene.spectra import (
    Layer,
    medium_index,
    normal_reflectance,
    stack_reflectance,
    wavelength_grid_nm,
)

# The tabulated constants are interpolated linearly between samples 10-50 nm apart; the
# metal checks compare with published reflectances quoted to 0.01.
PUBLISHED_TOL = 0.01
CLOSED_FORM_TOL = 1e-9  # transfer matrices vs closed forms: rounding only


def _r(medium: str, wavelength_nm: float) -> float:
    return float(normal_reflectance(medium_index(medium, np.array([wavelength_nm])))[0])


def test_grid_is_400_to_1800_nm_in_5_nm_steps() -> None:
    grid = wavelength_grid_nm()
    assert grid[0] == 400.0 and grid[-1] == 1800.0 and grid.size == 281
    assert np.all(np.diff(grid) == 5.0)


def test_aluminium_reflects_92_percent_at_550_nm() -> None:
    """Rakic (1995) evaporated Al: R(550 nm) = 0.916 (Bass, Handbook of Optics Vol. IV,
    ch. 12, gives 0.916 for Al at 550 nm; the paper quotes F0 = 0.91)."""
    assert _r("aluminium", 550.0) == pytest.approx(0.92, abs=PUBLISHED_TOL)


def test_silver_reflects_above_95_percent_at_600_nm() -> None:
    """Johnson & Christy (1972) Ag: R(600 nm) = 0.98-0.99."""
    assert _r("silver", 600.0) > 0.95


def test_gold_has_its_absorption_edge_between_450_and_650_nm() -> None:
    """Johnson & Christy (1972) Au: R = 0.38-0.41 at 450 nm (interband absorption of the d
    band), 0.95 at 650 nm; the edge is what makes gold yellow."""
    assert _r("gold", 450.0) < 0.45
    assert _r("gold", 650.0) > 0.90


@pytest.mark.parametrize("n", [1.0, 1.344, 1.5, 2.4, 4.0])
def test_bulk_dielectric_follows_the_fresnel_closed_form(n: float) -> None:
    assert float(normal_reflectance(n)) == pytest.approx(((n - 1) / (n + 1)) ** 2, abs=1e-15)


def test_stack_without_layers_equals_the_bulk_formula() -> None:
    wl = np.array([450.0, 700.0, 1500.0])
    sub = medium_index("gold", wl)
    np.testing.assert_allclose(stack_reflectance(wl, [], sub), normal_reflectance(sub), atol=1e-12)


def test_zero_thickness_coherent_film_equals_the_bare_substrate() -> None:
    wl = np.array([450.0, 550.0, 1200.0])
    sub = medium_index("aluminium", wl)
    film = Layer(medium_index("kapton_hn", wl), 0.0, coherent=True)
    np.testing.assert_allclose(
        stack_reflectance(wl, [film], sub), normal_reflectance(sub), atol=CLOSED_FORM_TOL
    )


def test_quarter_wave_mgf2_on_glass_gives_the_closed_form_minimum() -> None:
    """A lossless layer of index n_f and optical thickness lambda/4 on a substrate n_s:
    R = ((n_s - n_f^2) / (n_s + n_f^2))^2 at the design wavelength (Macleod, Thin-Film
    Optical Filters, section 3.2)."""
    lam = 550.0
    n_f, n_s = 1.38, 1.52
    film = Layer(np.array([n_f + 0j]), lam / (4 * n_f), coherent=True)
    r = stack_reflectance(np.array([lam]), [film], np.array([n_s + 0j]))[0]
    assert r == pytest.approx(((n_s - n_f**2) / (n_s + n_f**2)) ** 2, abs=CLOSED_FORM_TOL)
    assert r < ((n_s - 1) / (n_s + 1)) ** 2  # the coating reduces the reflectance


def test_thick_lossless_film_adds_powers_incoherently() -> None:
    """Incoherent film n on substrate n_s: R = R1 + (1-R1)^2 R2 / (1 - R1 R2)."""
    n, n_s = 1.5, 3.0
    r1 = ((n - 1) / (n + 1)) ** 2
    r2 = ((n_s - n) / (n_s + n)) ** 2
    expected = r1 + (1 - r1) ** 2 * r2 / (1 - r1 * r2)
    film = Layer(np.array([n + 0j]), 100e3, coherent=False)
    r = stack_reflectance(np.array([600.0]), [film], np.array([n_s + 0j]))[0]
    assert r == pytest.approx(expected, abs=CLOSED_FORM_TOL)


def test_polyimide_absorbs_blue_on_its_double_pass() -> None:
    """25 um Kapton on aluminium: the blue is absorbed (k = 5e-3 at 450 nm gives an
    absorption depth of 7 um), the near infrared reflected."""
    wl = np.array([450.0, 900.0])
    film = Layer(medium_index("kapton_hn", wl), 25e3, coherent=False)
    r = stack_reflectance(wl, [film], medium_index("aluminium", wl))
    assert r[0] < 0.15 and r[1] > 0.75


def test_unknown_medium_is_named() -> None:
    with pytest.raises(SatsightError, match="unobtainium"):
        medium_index("unobtainium", np.array([500.0]))
