"""Fitting the reflection models to BRDF tables: recovery, energy, metrics, files.

All data here are SYNTHETIC: values of the models themselves with Gaussian noise of known
standard deviation, made in code (or read from tests/brdf/fixtures/, which this file
regenerates and checks). They test the fit; they are not measurements of any material.

Recovery tolerance: the fit reports the parameter covariance from the Jacobian
((J^T J)^-1 with the uncertainty column, the sandwich estimate without); each recovered
parameter must lie within RECOVERY_SIGMAS of the truth (a false alarm per parameter has
probability ~6e-5 for a Gaussian estimate; the seeds are fixed).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from figure_checks import check_plane_of_incidence_figure
from satsight.brdf.fit import fit_brdf
from satsight.brdf.fit_files import fit_brdf_command, material_entry
from satsight.brdf.measurements import (
    BrdfMeasurements,
    measurements_from_degrees,
    read_brdf_csv,
    write_brdf_csv,
)
from satsight.brdf.metrics import fit_metrics
from satsight.brdf.parameters import (
    ALBEDO_TOLERANCE,
    evaluate_model,
    max_directional_albedo,
    unpack_parameters,
)
from satsight.errors import SatsightError

RECOVERY_SIGMAS = 4.0
DENSE_THETAS_DEG = tuple(np.linspace(0.0, 89.0, 30))
FIXTURES = Path(__file__).parent / "fixtures"


# --- synthetic tables -----------------------------------------------------------------------
def geometry(channels, thetas_i=(0.0, 20.0, 40.0, 60.0, 75.0), kind="band") -> BrdfMeasurements:
    """In-plane viewing angles -85..85 deg in 5 deg steps (signed: + on the specular side)
    and four out-of-plane directions, for each incidence angle and channel; BRDF zero."""
    rows = []
    for theta_i in thetas_i:
        views = [(abs(o), 180.0 if o >= 0 else 0.0) for o in np.arange(-85.0, 86.0, 5.0)]
        views += [(30.0, 90.0), (60.0, 90.0), (30.0, 135.0), (60.0, 135.0)]
        for theta_o, phi_o in views:
            for ch in channels:
                rows.append((theta_i, 0.0, theta_o, phi_o, ch))
    t_i, p_i, t_o, p_o, ch = zip(*rows, strict=True)
    return measurements_from_degrees(t_i, p_i, t_o, p_o, np.zeros(len(rows)), ch, kind)


def synthetic(m: BrdfMeasurements, model, truth, rel_sigma, abs_sigma, seed, with_sigma):
    """The table m with the model's values plus Gaussian noise of standard deviation
    rel_sigma * f + abs_sigma (given as the uncertainty column when with_sigma)."""
    params = unpack_parameters(model, np.asarray(truth, dtype=np.float64), m.n_channels)
    clean = evaluate_model(model, params, m.wi(), m.wo(), m.channel)
    sigma = rel_sigma * clean + abs_sigma
    noisy = clean + np.random.default_rng(seed).normal(size=clean.size) * sigma
    return measurements_from_degrees(
        np.degrees(m.theta_i_rad),
        np.degrees(m.phi_i_rad),
        np.degrees(m.theta_o_rad),
        np.degrees(m.phi_o_rad),
        noisy,
        [m.channel_names[c] for c in m.channel],
        m.channel_kind,
        uncertainty_per_sr=sigma if with_sigma else None,
    )


# The two shipped fixtures: what they are and how they are made.
FIXTURE_SPECS = {
    "synthetic_ggx_rgb.csv": dict(
        model="ggx",
        channels=("R", "G", "B"),
        kind="band",
        truth=(0.85, 0.80, 0.70, 0.3, 0.35, 1.5),  # base R G B, metallic, roughness, IOR
        rel_sigma=0.02,
        abs_sigma=0.002,
        seed=20240514,
        with_sigma=True,
    ),
    "synthetic_improved_phong_550nm.csv": dict(
        model="improved_phong",
        channels=("550",),
        kind="wavelength_nm",
        truth=(0.25, 0.6, 80.0, 0.4, 1.5, 1.0),  # kd, ks, g, a, b, c
        rel_sigma=0.0,
        abs_sigma=0.01,
        seed=20240515,
        with_sigma=False,
    ),
}


def make_fixture(name: str) -> BrdfMeasurements:
    spec = FIXTURE_SPECS[name]
    m = geometry(spec["channels"], kind=spec["kind"])
    table = synthetic(
        m,
        spec["model"],
        spec["truth"],
        spec["rel_sigma"],
        spec["abs_sigma"],
        spec["seed"],
        spec["with_sigma"],
    )
    return BrdfMeasurements(
        **{
            **table.__dict__,
            "metadata": {
                "material": "SYNTHETIC test data, not a measurement of any material",
                "source": f"satsight {spec['model']} model, parameters {spec['truth']}, "
                f"Gaussian noise {spec['rel_sigma']} f + {spec['abs_sigma']} sr^-1, "
                f"seed {spec['seed']} (tests/scene/test_brdf_fit.py::make_fixture)",
                "licence": "same as satsight (MIT)",
            },
        }
    )


def write_fixtures() -> None:  # pragma: no cover - run by hand to refresh the fixtures
    FIXTURES.mkdir(exist_ok=True)
    for name in FIXTURE_SPECS:
        write_brdf_csv(FIXTURES / name, make_fixture(name))


# --- tests ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FIXTURE_SPECS))
def test_fixtures_are_what_their_header_says(name):
    on_disk = read_brdf_csv(FIXTURES / name)
    made = make_fixture(name)
    assert "SYNTHETIC" in on_disk.metadata["material"]
    assert on_disk.channel_names == made.channel_names
    np.testing.assert_allclose(on_disk.brdf_per_sr, made.brdf_per_sr, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(on_disk.theta_o_rad, made.theta_o_rad, atol=1e-12)


RECOVERY_CASES = [
    ("phong", ("R", "G", "B"), (0.30, 0.20, 0.10, 0.40, 0.40, 0.40, 40.0), 1),
    ("phong", ("V",), (0.05, 0.90, 900.0), 2),
    ("improved_phong", ("R", "G", "B"), (0.3, 0.2, 0.1, 0.4, 0.4, 0.4, 40.0, 0.3, 0.8, 0.7), 3),
    ("improved_phong", ("V",), (0.5, 0.3, 15.0, 0.6, 2.0, 1.5), 4),
    ("ggx", ("R", "G", "B"), (0.8, 0.5, 0.2, 0.3, 0.35, 1.6), 5),
    ("ggx", ("R", "G", "B"), (0.95, 0.75, 0.35, 0.7, 0.2, 1.5), 6),
]


@pytest.mark.parametrize(("model", "channels", "truth", "seed"), RECOVERY_CASES)
@pytest.mark.parametrize("with_sigma", [False, True])
def test_fit_recovers_known_parameters(model, channels, truth, seed, with_sigma):
    """Noise 1 % of the value plus 0.3 % of the peak; with and without the uncertainty
    column (then the scale comes from the residuals)."""
    base = geometry(channels)
    params = unpack_parameters(model, np.asarray(truth, dtype=float), len(channels))
    peak = float(np.max(evaluate_model(model, params, base.wi(), base.wo(), base.channel)))
    m = synthetic(base, model, truth, 0.01, 0.003 * peak, seed, with_sigma)
    fit = fit_brdf(m, model)
    assert fit.success
    assert not fit.at_bounds
    z = (fit.values - np.asarray(truth)) / fit.std
    assert np.all(np.abs(z) < RECOVERY_SIGMAS), dict(zip(fit.names, np.round(z, 2), strict=True))
    dof = m.size - len(fit.names)
    if with_sigma:
        # chi^2 / dof of a correct model has mean 1 and standard deviation sqrt(2 / dof).
        assert abs(fit.reduced_chi2 - 1.0) < RECOVERY_SIGMAS * math.sqrt(2.0 / dof)
    else:
        # The residuals' mean square, per degree of freedom, estimates the mean variance of
        # the generating noise; a sum of dof squared Gaussians of variances sigma_i^2 has
        # relative standard deviation sqrt(2 sum sigma^4) / sum sigma^2.
        sigma = 0.01 * evaluate_model(model, params, base.wi(), base.wo(), base.channel)
        sigma += 0.003 * peak
        noise_ms = float(np.mean(sigma**2))
        rel_spread = math.sqrt(2.0 * np.sum(sigma**4)) / np.sum(sigma**2)
        residual_ms = fit.metrics.mse_sr2 * m.size / dof
        assert abs(residual_ms / noise_ms - 1.0) < RECOVERY_SIGMAS * rel_spread
    albedo, _ = max_directional_albedo(model, fit.parameters, thetas_deg=DENSE_THETAS_DEG)
    assert albedo <= 1.0 + ALBEDO_TOLERANCE


@pytest.mark.parametrize("model", ["phong", "improved_phong", "ggx"])
def test_fit_to_brighter_than_white_data_stays_energy_conserving(model):
    """A table of 0.5 sr^-1 everywhere would need a Lambertian albedo of pi / 2: the best
    physical fit has kd + ks <= 1 and albedo <= 1 at every incidence angle."""
    m0 = geometry(("R", "G", "B"))
    m = BrdfMeasurements(**{**m0.__dict__, "brdf_per_sr": np.full(m0.size, 0.5)})
    fit = fit_brdf(m, model)
    p = fit.parameters
    if model != "ggx":
        assert np.all(p["kd"] + p["ks"] <= 1.0 + 1e-12)
    albedo, _ = max_directional_albedo(model, p, fit.masking, DENSE_THETAS_DEG)
    assert albedo <= 1.0 + ALBEDO_TOLERANCE
    assert fit.max_albedo <= 1.0 + ALBEDO_TOLERANCE


def test_metrics_of_a_perfect_fit():
    for channels in (("R", "G", "B"), ("550",)):
        m0 = geometry(channels, kind="band")
        truth = (0.3,) * len(channels) + (0.5,) * len(channels) + (50.0,)
        params = unpack_parameters("phong", np.array(truth), len(channels))
        values = evaluate_model("phong", params, m0.wi(), m0.wo(), m0.channel)
        m = BrdfMeasurements(**{**m0.__dict__, "brdf_per_sr": values})
        metrics = fit_metrics(m, values)
        assert metrics.mse_sr2 == 0.0
        assert metrics.psnr_db == math.inf
        assert metrics.angular_error_deg == 0.0
        assert metrics.peak_direction_error_deg == 0.0
        assert (metrics.spectral_angle_deg is None) == (len(channels) == 1)


def test_metrics_closed_forms():
    """A constant offset d: MSE = d^2, PSNR = 20 log10(peak / d); a fitted vector (1, 1)
    against a measured (1, 0): spectral angle 45 deg; a peak moved by one 5 deg step."""
    m = measurements_from_degrees(
        [30.0] * 4,
        [0.0] * 4,
        [25.0, 25.0, 30.0, 30.0],
        [180.0] * 4,
        [1.0, 0.0, 2.0, 0.0],
        ["R", "G", "R", "G"],
    )
    offset = fit_metrics(m, m.brdf_per_sr + 0.1)
    assert offset.mse_sr2 == pytest.approx(0.01)
    assert offset.psnr_db == pytest.approx(20.0 * math.log10(2.0 / 0.1))
    rotated = fit_metrics(m, np.array([1.0, 1.0, 2.0, 2.0]))
    assert rotated.spectral_angle_deg == pytest.approx(45.0)
    moved = fit_metrics(m, np.array([2.0, 0.0, 1.0, 0.0]))
    assert moved.peak_direction_error_deg == pytest.approx(5.0)


def test_material_entry_is_accepted_by_the_renderer_and_the_library():
    from satsight.render.ggx import validate_ggx_parameters
    from satsight.render.phong import validate_improved_phong_parameters
    from satsight.scene.materials import Material

    base = geometry(("R", "G", "B"))
    m = synthetic(base, "improved_phong", RECOVERY_CASES[2][2], 0.01, 0.003, 7, False)
    entry = material_entry(fit_brdf(m, "improved_phong"))
    p = entry["parameters"]
    assert entry["model"] == "improved_phong"
    assert set(p) == {"kd_rgb", "ks_rgb", "g", "a", "b", "c"}
    validate_improved_phong_parameters(p["kd_rgb"], p["ks_rgb"], p["g"], p["a"], p["b"], p["c"])
    assert set(entry["metrics"]) >= {"mse_sr2", "psnr_db", "angular_error_deg"}
    assert set(entry["library_brdf"]) == {
        "gloss_exponent_g",
        "fresnel_exponent_a",
        "lobe_decay_b",
        "diffuse_exponent_c",
    }
    assert entry["library_brdf"]["fresnel_exponent_a"]["value"] == p["a"]

    m = synthetic(base, "ggx", RECOVERY_CASES[4][2], 0.01, 0.003, 8, False)
    p = material_entry(fit_brdf(m, "ggx"))["parameters"]
    validate_ggx_parameters(p["base_color_rgb"], p["metallic"], p["roughness"], p["ior"])
    Material("fitted", tuple(p["base_color_rgb"]), p["metallic"], p["roughness"], p["ior"])


def test_command_fits_a_fixture_and_writes_yaml_and_plot(tmp_path):
    spec = FIXTURE_SPECS["synthetic_ggx_rgb.csv"]
    report = fit_brdf_command(FIXTURES / "synthetic_ggx_rgb.csv", "ggx", tmp_path / "out")
    assert report.yaml_path == tmp_path / "out" / "synthetic_ggx_rgb_ggx.yaml"
    # Three channels, the five incidence angles of ``geometry``.
    check_plane_of_incidence_figure(report.plot_path, n_channels=3, n_incidences=5)
    entry = yaml.safe_load(report.yaml_path.read_text())
    assert entry["model"] == "ggx"
    assert entry["source"]["csv"].endswith("synthetic_ggx_rgb.csv")
    assert "SYNTHETIC" in entry["source"]["provenance"]["material"]
    assert len(entry["source"]["sha256"]) == 64
    fit = report.fit
    assert fit.weighted
    z = (fit.values - np.asarray(spec["truth"])) / fit.std
    assert np.all(np.abs(z) < RECOVERY_SIGMAS)
    table = report.table()
    for word in ("metallic", "roughness", "ior", "PSNR", "MSE", "angular error", "wrote"):
        assert word in table


def test_command_on_single_wavelength_fixture(tmp_path):
    report = fit_brdf_command(
        FIXTURES / "synthetic_improved_phong_550nm.csv", "improved_phong", tmp_path
    )
    entry = yaml.safe_load(report.yaml_path.read_text())
    assert set(entry["parameters"]) == {"kd", "ks", "g", "a", "b", "c"}
    assert entry["channels"] == {"kind": "wavelength_nm", "names": ["550"]}
    assert "peak directions" in entry["metrics"]["angular_error_definition"]
    assert entry["metrics"]["spectral_angle_deg"] is None


def test_phong_fits_improved_phong_data_worse():
    """Ablation in the spirit of the paper's Table 4: on data made by the improved model
    (grazing factor a, lobe decay b, diffuse exponent c), Phong fits worse."""
    m = read_brdf_csv(FIXTURES / "synthetic_improved_phong_550nm.csv")
    improved = fit_brdf(m, "improved_phong").metrics
    phong = fit_brdf(m, "phong").metrics
    assert improved.mse_sr2 < phong.mse_sr2
    assert improved.psnr_db > phong.psnr_db


def test_errors():
    m = geometry(("R",), thetas_i=(30.0,))
    with pytest.raises(SatsightError, match="unknown BRDF model 'blinn'"):
        fit_brdf(m, "blinn")
    with pytest.raises(SatsightError, match="unknown GGX masking"):
        fit_brdf(m, "ggx", masking="beckmann")
    tiny = measurements_from_degrees(
        [30.0] * 3, [0.0] * 3, [10, 20, 30], [180.0] * 3, [1, 2, 3], "RRR"
    )
    with pytest.raises(SatsightError, match="cannot determine"):
        fit_brdf(tiny, "improved_phong")
