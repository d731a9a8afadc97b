"""`satsight materials`: the library's table, its JSON and its figure, and bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from cli_runner import invoke_satsight, run_satsight
from figure_checks import check_plane_of_incidence_figure, figure_pixels, has_colour
from satsight.scene.band_reflectance import material_rgb_reflectance
from satsight.scene.material_library import load_library


def test_materials_lists_every_library_entry_with_its_band_reflectance(tmp_path: Path) -> None:
    result = run_satsight(
        "materials", "--band", "500,800", "--qe", "flat", "--out", "m", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    document = json.loads((tmp_path / "m" / "materials.json").read_text(encoding="utf-8"))
    assert document["band_nm"] == [500.0, 800.0] and document["quantum_efficiency"] == "flat"
    library = load_library()
    rows = {row["name"]: row for row in document["materials"]}
    assert set(rows) == set(library) and len(rows) >= 16
    for name, row in rows.items():
        # The table rounds to 3 decimals: the band integration of the same entry.
        expected = material_rgb_reflectance(library[name], (500.0, 800.0), "flat")
        assert row["rgb"] == pytest.approx(expected, abs=5e-4)
        assert name in result.stdout
    # A 2 x 2 grid of 12 x 8.5 inches at 110 dpi; the band shaded in grey 0.9, the spectra
    # drawn in matplotlib's colour cycle.
    figure = figure_pixels(tmp_path / "m" / "material_spectra.png", (12 * 110, round(8.5 * 110)))
    assert has_colour(figure, to_rgba("0.9")) and has_colour(figure, to_rgba("C0"))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--band", "900,450"], "0 < lo < hi"),
        (["--band", "450"], "--band must be two wavelengths"),
        (["--qe", "nope"], "Invalid value for '--qe'"),
    ],
)
def test_bad_options_exit_2_with_a_message(tmp_path: Path, args, message) -> None:
    result = run_satsight("materials", *args, "--out", "m", cwd=tmp_path)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "m").exists()


FIXTURES = Path(__file__).parent / "brdf" / "fixtures"


# The GGX fixture's generating parameters, as its header states them.
GGX_FIXTURE_TRUTH = {"base_color_rgb": (0.85, 0.80, 0.70), "metallic": 0.3, "roughness": 0.35,
                     "ior": 1.5}  # fmt: skip
# A fitted parameter lies within this many of its 1-sigma uncertainties of the truth (a
# false alarm has probability ~6e-5 per parameter for a Gaussian estimate).
RECOVERY_SIGMAS = 4.0


def test_fit_brdf_writes_parameters_and_plot_and_recovers_the_generating_model(
    tmp_path: Path,
) -> None:
    """The GGX fixture (synthetic: the GGX model plus Gaussian noise of 2 % of the value and
    0.002 sr^-1, given as its uncertainty column) fitted with GGX: the parameters the command
    writes lie within RECOVERY_SIGMAS of their reported uncertainties (from the noise and the
    585 measurements) of the generating ones, and chi^2 per degree of freedom is 1 within
    RECOVERY_SIGMAS of its spread sqrt(2 / dof)."""
    import yaml

    csv = FIXTURES / "synthetic_ggx_rgb.csv"
    result = run_satsight("fit-brdf", str(csv), "--model", "ggx", "--out", "fit", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "PSNR" in result.stdout and "angular error" in result.stdout
    entry = yaml.safe_load((tmp_path / "fit" / "synthetic_ggx_rgb_ggx.yaml").read_text())
    assert entry["model"] == "ggx"
    truth = GGX_FIXTURE_TRUTH
    assert "parameters (0.85, 0.8, 0.7, 0.3, 0.35, 1.5)" in entry["source"]["provenance"]["source"]
    fitted, std = entry["parameters"], entry["parameters_std"]
    for name, value in truth.items():
        error = np.abs(np.subtract(fitted[name], value))
        assert np.all(error < RECOVERY_SIGMAS * np.asarray(std[name])), (name, fitted[name], value)
    fit = entry["fit"]
    dof = fit["n_measurements"] - fit["n_parameters"]
    assert fit["weighted_by_uncertainty"] and (fit["n_measurements"], dof) == (585, 579)
    assert abs(fit["reduced_chi2"] - 1.0) < RECOVERY_SIGMAS * math.sqrt(2.0 / dof)
    # Three channels, each with the fixture's five incidence angles.
    plot = tmp_path / "fit" / "synthetic_ggx_rgb_ggx_plane.png"
    check_plane_of_incidence_figure(plot, n_channels=3, n_incidences=5)


def test_fit_brdf_names_the_bad_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text(
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band,brdf_per_sr\n"
        "10,0,20,180,V,0.3\n10,0,x,180,V,0.3\n",
        encoding="utf-8",
    )
    result = invoke_satsight("fit-brdf", str(bad), "--model", "phong", "--out", "fit", cwd=tmp_path)
    assert result.returncode == 2
    assert "line 3" in result.stderr and "theta_o_deg" in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "fit").exists()


def test_piped_table_keeps_every_name_and_number_whole(tmp_path: Path, monkeypatch) -> None:
    """Not on a terminal (CliRunner's output is a buffer, 80 columns by default): every row
    comes out whole, tab-separated, with the same numbers as the JSON."""
    from click.testing import CliRunner

    from satsight.cli import cli

    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli, ["materials", "--out", "m"])
    assert result.exit_code == 0, result.output
    assert "…" not in result.stdout
    lines = result.stdout.splitlines()
    assert lines[0].startswith("# material library: in-band reflectance over 450-900 nm")
    assert lines[1].split("\t") == ["material", "category", "r", "g", "b", "M", "R", "IOR",
                                    "spectrum"]  # fmt: skip
    document = json.loads((tmp_path / "m" / "materials.json").read_text(encoding="utf-8"))
    rows = {line.split("\t")[0]: line.split("\t") for line in lines[2:] if line}
    assert "radiator_osr_ceria_glass" in rows  # the longest name
    for entry in document["materials"]:
        r, g, b = entry["rgb"]
        assert rows[entry["name"]][1:6] == [
            entry["category"], f"{r:.3f}", f"{g:.3f}", f"{b:.3f}", f"{entry['metallic']:.2f}"
        ]  # fmt: skip


def test_shipped_brdf_example_is_packaged_and_fits(tmp_path: Path) -> None:
    """The README's fit-brdf example: in the installed package, named by the wheel's
    package-data, and fitted by the command with the parameters its header gives."""
    import fnmatch
    import tomllib
    from importlib import resources

    import yaml
    from click.testing import CliRunner

    from satsight.cli import cli

    shipped = resources.files("satsight") / "examples" / "brdf_synthetic_ggx_rgb.csv"
    assert shipped.is_file()
    pyproject = Path(__file__).parents[1] / "pyproject.toml"
    globs = tomllib.loads(pyproject.read_text(encoding="utf-8"))["tool"]["setuptools"]
    assert any(
        fnmatch.fnmatch("examples/brdf_synthetic_ggx_rgb.csv", pattern)
        for pattern in globs["package-data"]["satsight"]
    )
    result = CliRunner().invoke(
        cli, ["fit-brdf", str(shipped), "--model", "ggx", "--out", str(tmp_path / "fit")]
    )
    assert result.exit_code == 0, result.output
    assert "BRDF fit: ggx" in result.stdout and "585 measurements" in result.stdout
    fitted = yaml.safe_load((tmp_path / "fit" / "brdf_synthetic_ggx_rgb_ggx.yaml").read_text())
    # The header's generating parameters: base colour, metallic, roughness, IOR.
    assert fitted["parameters"]["base_color_rgb"] == pytest.approx([0.85, 0.80, 0.70], abs=0.02)
    assert fitted["parameters"]["roughness"] == pytest.approx(0.35, abs=0.01)
