"""The material library: every file loads with sources, spectra in range and covering
400-1800 nm, the gold MLI is yellow, each Material conserves energy, errors name the
file and field."""

from __future__ import annotations

import math
import shutil
from collections import Counter

import numpy as np
import pytest
from matplotlib import colormaps

from chi2_helpers import direction, importance_sampled_albedo
from figure_checks import figure_pixels, has_colour
from satsight.errors import SatsightError
from satsight.scene.band_reflectance import material_from_entry, material_rgb_reflectance
from satsight.scene.material_library import (
    CATEGORIES,
    entry_spectrum,
    library_dir,
    list_materials,
    load_entry,
    load_library,
)
from satsight.scene.material_plot import format_report, materials_report, plot_library_spectra
from satsight.scene.materials import Material

MC_SIGMAS = 5.0  # one-sided Monte Carlo bound: a false alarm has probability 3e-7 per case
MC_SAMPLES = 20_000


@pytest.fixture(scope="module")
def library():
    return load_library()


def test_at_least_16_materials_in_all_four_categories(library) -> None:
    assert len(library) >= 16
    assert {e.category for e in library.values()} == set(CATEGORIES)


def test_every_value_has_a_source(library) -> None:
    for entry in library.values():
        assert entry.spectrum_source
        assert all(sv.source for sv in entry.brdf.values())
        assert all(sv.source for sv in entry.reference.values())
        if entry.computed is not None:
            assert all(src for *_, src in entry.computed.layers)


def test_assumed_shapes_say_so(library) -> None:
    for entry in library.values():
        if entry.spectrum_kind == "table":
            assert "shape assumed" in entry.spectrum_source, entry.name


def test_spectra_cover_400_to_1800_nm_within_0_and_1(library) -> None:
    for entry in library.values():
        wl, refl = entry_spectrum(entry)
        assert wl[0] == 400.0 and wl[-1] == 1800.0
        assert np.all(np.isfinite(refl)) and np.all((refl >= 0.0) & (refl <= 1.0)), entry.name


def test_gold_mli_is_yellow_from_polyimide_absorption() -> None:
    """Red and green (600-900 nm) reflect well, blue (450-600 nm) is absorbed by the
    polyimide. The green third (600-750 nm) reflects about 1 % more than the red
    (750-900 nm): aluminium's interband absorption near 826 nm, visible in its spectrum."""
    r, g, b = material_rgb_reflectance("mli_aluminised_kapton", (450, 900))
    assert b < 0.75 * min(r, g)
    assert abs(r - g) < 0.03
    assert min(r, g) > 0.7


def test_gold_metal_is_red_over_green_over_blue() -> None:
    r, g, b = material_rgb_reflectance("gold", (450, 900))
    assert r > g > b


def test_changing_the_band_changes_the_materials_consistently() -> None:
    """The same spectrum seen in 400-700 nm: gold's blue third (400-500 nm) is darker."""
    wide = material_from_entry("gold", (450, 900))
    visible = material_from_entry("gold", (400, 700))
    assert visible.base_color_rgb[2] < wide.base_color_rgb[2]
    assert "400-700 nm" in visible.source


@pytest.mark.usefixtures("llvm_variant")
def test_every_material_conserves_energy(library) -> None:
    """Directional albedo of the GGX model (paper masking) <= 1 at incidence 0-85 deg, by
    importance sampling with a 5-sigma allowance."""
    from satsight.render.ggx import GGXParams, ggx_eval, ggx_sample

    for i, entry in enumerate(library.values()):
        m = material_from_entry(entry)
        assert isinstance(m, Material)
        params = GGXParams.from_values(m.base_color_rgb, m.metallic, m.roughness, m.ior)
        for j, theta in enumerate((0.0, 45.0, 70.0, 85.0)):
            mean, stderr = importance_sampled_albedo(
                ggx_sample, ggx_eval, params, direction(theta, 15.0), MC_SAMPLES, 100 * i + j, False
            )
            assert np.all(mean <= 1.0 + MC_SIGMAS * stderr + 1e-4), (entry.name, theta, mean)


def test_report_rows_and_table(library) -> None:
    rows = materials_report((450, 900))
    assert [r["name"] for r in rows] == list(library)
    text = format_report(rows)
    assert "mli_aluminised_kapton" in text and "white_paint_az93" in text


def test_plot_shows_every_category_with_the_band_shaded(tmp_path) -> None:
    out = plot_library_spectra(tmp_path / "spectra.png")
    # 12 x 8.5 inches at 110 dpi; the shaded band is grey 0.9; each panel's curves take
    # the default colour cycle from its start, so the busiest panel shows that many colours.
    pixels = figure_pixels(out, (1320, 935))
    assert has_colour(pixels, (0.9, 0.9, 0.9), atol=1)
    per_panel = max(Counter(e.category for e in load_library().values()).values())
    assert all(has_colour(pixels, colormaps["tab10"](k)) for k in range(min(per_panel, 10)))


def _copy_library(tmp_path):
    for name in [*list_materials(), "media"]:
        shutil.copy(str(library_dir() / f"{name}.yaml"), tmp_path)
    for p in library_dir().iterdir():
        if p.name.endswith(".csv"):
            shutil.copy(str(p), tmp_path)
    return tmp_path


def test_malformed_file_names_file_and_field(tmp_path) -> None:
    root = _copy_library(tmp_path)
    path = root / "gold.yaml"
    path.write_text(path.read_text().replace("roughness:", "roughnes:"))
    with pytest.raises(SatsightError, match=r"gold\.yaml.*brdf\.roughness"):
        load_entry("gold", root)


def test_value_without_source_is_refused(tmp_path) -> None:
    root = _copy_library(tmp_path)
    path = root / "titanium.yaml"
    text = path.read_text()
    start = text.index("    source: 'assumed: machined'")
    path.write_text(text[:start] + text[start:].split("\n", 1)[1])
    with pytest.raises(SatsightError, match=r"titanium\.yaml.*brdf\.roughness\.source"):
        load_entry("titanium", root)


def test_table_out_of_range_is_refused(tmp_path) -> None:
    root = _copy_library(tmp_path)
    (root / "cfrp.csv").write_text("wavelength_nm,reflectance\n400,0.1\n1800,1.2\n")
    entry = load_entry("cfrp", root)
    with pytest.raises(SatsightError, match=r"cfrp\.csv.*\[0, 1\]"):
        entry_spectrum(entry, root)


def test_unknown_material_lists_the_known_ones() -> None:
    with pytest.raises(SatsightError, match="mli_aluminised_kapton"):
        load_entry("unobtainium")


@pytest.mark.parametrize("name", list_materials())
def test_every_library_material_conserves_energy_at_every_incidence(name: str) -> None:
    """Directional albedo of each library material's GGX BRDF (paper masking and the exact
    Smith masking) <= 1 from normal incidence to 88 deg in 4 deg steps, by the deterministic
    quadrature of ``brdf.models.directional_albedo`` (accurate to ~2e-4 near the horizon,
    so the bound allows 1e-3)."""
    from satsight.brdf.models import directional_albedo, ggx_brdf

    m = material_from_entry(name)
    base = np.asarray(m.base_color_rgb)
    width = max(m.roughness**2, 1e-3) * 2.0
    worst = 0.0
    for masking in ("schlick", "smith"):

        def brdf(wi, wo, masking=masking):
            w_i, w_o = wi[..., None, :], wo[..., None, :]  # a channel axis before xyz
            return ggx_brdf(w_i, w_o, base, m.metallic, m.roughness, m.ior, masking=masking)

        for theta_deg in range(0, 89, 4):
            albedo = directional_albedo(brdf, math.radians(theta_deg), lobe_width_rad=width)
            worst = max(worst, float(np.max(albedo)))
    assert worst <= 1.0 + 1e-3, f"{name}: largest directional albedo {worst:.5f}"
