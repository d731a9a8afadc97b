"""Phong (paper Eq. 16) and improved Phong (Eq. 17) models against their definitions.

Each BRDF is checked against its formula written out in float64 numpy, for energy (the
directional albedo by a deterministic quadrature and by importance-sampled Monte Carlo
with a tolerance from the sample variance), and its sampler against its pdf with a
chi-square test. The improved model's normalisation is checked against an independent
brute-force integration on a dense spherical grid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chi2_helpers import (
    check_pdf_integral_is_valid_fraction,
    check_sample_density_is_pdf,
    chi2_direction_test,
    direction,
    hemisphere_integral,
    importance_sampled_albedo,
    pdf_callable,
    quadrature_albedo,
    sample_directions,
)
from chi2_helpers import to_numpy as _np
from chi2_helpers import to_vector3f as _vec
from satsight.errors import SatsightError
from satsight.render.phong import (
    MU_MIN,
    ImprovedPhongParams,
    PhongParams,
    improved_phong_diffuse_coefficient,
    improved_phong_eval,
    improved_phong_eval_specular,
    improved_phong_lobe_albedo,
    improved_phong_max_lobe_albedo,
    improved_phong_normalization,
    improved_phong_pdf,
    improved_phong_sample,
    phong_diffuse_coefficient,
    phong_eval,
    phong_eval_specular,
    phong_pdf,
    phong_sample,
)

pytestmark = pytest.mark.usefixtures("llvm_variant")

FLOAT32_RTOL = 1e-4  # float32 arithmetic against float64, cos^g with g up to a few hundred
QUADRATURE_ATOL = 2e-3  # albedo quadrature with float32 BRDF values, g up to 1e5
BRUTE_FORCE_RTOL = 3e-4  # dense midpoint grid of 300 x 600 cells, lobes with g <= 40
MC_SIGMAS = 5.0  # one-sided Monte Carlo bound: a false alarm has probability 3e-7
CHI2_CASES = 8  # chi-square tests in this file (Bonferroni-corrected significance)
CHI2_SIGNIFICANCE = 0.01 / CHI2_CASES
CHI2_SAMPLES = 200_000


def _random_directions(rng, n: int, upper: bool = False) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if upper:
        d[:, 2] = np.abs(d[:, 2])
    return d.astype(np.float32).astype(np.float64)


# --- float64 references ----------------------------------------------------------------------
def _cos_beta(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    return np.maximum(np.sum(wi * (wo * [-1.0, -1.0, 1.0]), axis=1), 0.0)


def _phong_reference(wi, wo, kd, ks, g):
    lobe = (g + 2.0) / (2.0 * math.pi) * _cos_beta(wi, wo) ** g
    f = kd / math.pi + ks * lobe[:, None]
    valid = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return np.where(valid[:, None], f, 0.0)


def _improved_reference(wi, wo, kd, ks, g, a, b, c):
    norm = np.array([improved_phong_normalization(*t) for t in zip(g, a, b, strict=True)])
    cb = _cos_beta(wi, wo)
    cos_i = np.maximum(wi[:, 2], 0.0)
    shape = cb**g * np.exp(-b * (1.0 - cb) ** (1.0 / math.pi)) / np.maximum(cos_i, MU_MIN) ** a
    f = kd / math.pi * (cos_i**c)[:, None] + ks * (norm * shape)[:, None]
    valid = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return np.where(valid[:, None], f, 0.0)


def _random_materials(rng, n: int):
    total = rng.uniform(0.0, 1.0, (n, 3))
    split = rng.uniform(0.0, 1.0, (n, 3))
    return total * split, total * (1.0 - split), rng.uniform(1.0, 200.0, n)


# --- evaluation --------------------------------------------------------------------------------
def test_phong_matches_float64_formula_per_lane() -> None:
    rng = np.random.default_rng(11)
    n = 4000
    wi, wo = _random_directions(rng, n), _random_directions(rng, n)
    kd, ks, g = _random_materials(rng, n)
    f = _np(phong_eval(_vec(wi), _vec(wo), PhongParams.from_values(kd, ks, g)))
    np.testing.assert_allclose(f, _phong_reference(wi, wo, kd, ks, g), rtol=FLOAT32_RTOL, atol=1e-7)


def test_improved_phong_matches_float64_formula_per_lane() -> None:
    rng = np.random.default_rng(12)
    n = 4000
    wi, wo = _random_directions(rng, n), _random_directions(rng, n)
    kd, ks, _ = _random_materials(rng, n)
    # Eight distinct (g, a, b) lobes spread over the lanes, each with its own normalisation.
    table = np.array(
        [
            [1.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
            [10.0, 0.5, 1.0],
            [50.0, 0.2, 4.0],
            [120.0, 0.8, 0.3],
            [2.0, 0.05, 10.0],
            [30.0, 0.0, 2.0],
            [7.0, 1.0, 0.7],
        ]
    )
    g, a, b = table[rng.integers(0, len(table), n)].T
    c = rng.uniform(0.0, 3.0, n)
    params = ImprovedPhongParams.from_values(kd, ks, g, a, b, c)
    f = _np(improved_phong_eval(_vec(wi), _vec(wo), params))
    expected = _improved_reference(wi, wo, kd, ks, g, a, b, c)
    np.testing.assert_allclose(f, expected, rtol=FLOAT32_RTOL, atol=1e-6)


def test_improved_phong_with_neutral_parameters_is_phong() -> None:
    rng = np.random.default_rng(13)
    n = 5000
    wi, wo = _random_directions(rng, n), _random_directions(rng, n)
    kd, ks, g = _random_materials(rng, n)
    g[:100] = rng.uniform(1000.0, 1e5, 100)
    phong = _np(phong_eval(_vec(wi), _vec(wo), PhongParams.from_values(kd, ks, g)))
    improved = ImprovedPhongParams.from_values(kd, ks, g, a=0.0, b=0.0, c=0.0)
    np.testing.assert_allclose(
        _np(improved_phong_eval(_vec(wi), _vec(wo), improved)), phong, rtol=2e-7
    )
    assert np.all(_np(improved.lobe_scale) == 1.0)


@pytest.mark.parametrize("model", ["phong", "improved"])
def test_brdf_is_non_negative_finite_and_zero_below_the_horizon(model) -> None:
    rng = np.random.default_rng(14)
    n = 20000
    wi, wo = _random_directions(rng, n), _random_directions(rng, n)
    wi[:50, 2] = 0.0  # exactly grazing light
    kd, ks, g = _random_materials(rng, n)
    if model == "phong":
        f = _np(phong_eval(_vec(wi), _vec(wo), PhongParams.from_values(kd, ks, g)))
    else:
        a = rng.choice([0.0, 0.4, 1.0], n)
        g = rng.choice([1.0, 4.0, 30.0, 500.0], n)  # a few lobes, each normalised once
        params = ImprovedPhongParams.from_values(kd, ks, g, a, 0.5, 1.0)
        f = _np(improved_phong_eval(_vec(wi), _vec(wo), params))
    assert np.all(np.isfinite(f))
    assert np.all(f >= 0.0)
    below = (wi[:, 2] <= 0.0) | (wo[:, 2] <= 0.0)
    assert np.all(f[below] == 0.0)
    assert np.any(f[~below] > 0.0)


@pytest.mark.parametrize("model", ["phong", "improved"])
def test_diffuse_coefficient_is_the_diffuse_part(model) -> None:
    """eval - eval_specular = kd_eq / pi cos^exponent(theta_i) exactly for both models."""
    rng = np.random.default_rng(15)
    n = 3000
    wi, wo = _random_directions(rng, n, upper=True), _random_directions(rng, n, upper=True)
    kd, ks, g = _random_materials(rng, n)
    if model == "phong":
        params = PhongParams.from_values(kd, ks, g)
        full, spec = phong_eval, phong_eval_specular
        kd_eq, exponent = phong_diffuse_coefficient(params)
    else:
        params = ImprovedPhongParams.from_values(kd, ks, 20.0, 0.3, 1.0, rng.uniform(0, 2, n))
        full, spec = improved_phong_eval, improved_phong_eval_specular
        kd_eq, exponent = improved_phong_diffuse_coefficient(params)
    diffuse = _np(full(_vec(wi), _vec(wo), params)) - _np(spec(_vec(wi), _vec(wo), params))
    kd_eq, exponent = _np(kd_eq), np.broadcast_to(_np(exponent), (n,))
    np.testing.assert_allclose(kd_eq, np.broadcast_to(kd.astype(np.float32), (n, 3)))
    expected = kd_eq / math.pi * (wi[:, 2] ** exponent)[:, None]
    np.testing.assert_allclose(diffuse, expected, rtol=1e-4, atol=1e-6)
    if model == "phong":
        assert np.all(exponent == 0.0)


# --- energy --------------------------------------------------------------------------------------
@pytest.mark.parametrize("g", [1.0, 2.5, 10.0, 100.0, 1000.0, 1e4, 1e5])
def test_phong_albedo_at_normal_incidence_is_kd_plus_ks(g) -> None:
    kd, ks = np.array([0.3, 0.1, 0.0]), np.array([0.7, 0.5, 0.2])
    params = PhongParams.from_values(kd, ks, g)
    albedo = quadrature_albedo(phong_eval, params, direction(0.0), math.sqrt(2 / (g + 2)), False)
    np.testing.assert_allclose(albedo, kd + ks, atol=QUADRATURE_ATOL)


materials = st.tuples(
    st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
    st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
).map(lambda t: (np.array(t[0]) * np.array(t[1]), np.array(t[0]) * (1.0 - np.array(t[1]))))
gloss = st.floats(0.0, 5.0).map(lambda e: 10.0**e)  # g from 1 to 1e5, log-uniform


@settings(max_examples=25, deadline=None, derandomize=True)
@given(kd_ks=materials, g=gloss, theta_deg=st.floats(0.0, 89.9), seed=st.integers(0, 2**31))
def test_phong_white_furnace(kd_ks, g, theta_deg, seed) -> None:
    """The directional albedo never exceeds kd + ks <= 1 (and is kd + ks at normal view)."""
    kd, ks = kd_ks
    params = PhongParams.from_values(kd, ks, g)
    wo = direction(theta_deg, 40.0)
    mean, stderr = importance_sampled_albedo(
        phong_sample, phong_eval, params, wo, 100_000, seed, False
    )
    assert np.all(mean <= kd + ks + MC_SIGMAS * stderr + 1e-6), (mean, stderr, kd + ks)


lobe_shapes = st.tuples(gloss, st.floats(0.0, 1.0), st.floats(0.0, 20.0), st.floats(0.0, 4.0))


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    kd_ks=materials, shape=lobe_shapes, theta_deg=st.floats(0.0, 89.9), seed=st.integers(0, 2**31)
)
def test_improved_phong_conserves_energy(kd_ks, shape, theta_deg, seed) -> None:
    """Light from a fixed direction: reflected power over the viewer hemisphere <= kd + ks."""
    kd, ks = kd_ks
    g, a, b, c = shape
    params = ImprovedPhongParams.from_values(kd, ks, g, a, b, c)
    wi = direction(theta_deg, -70.0)
    mean, stderr = importance_sampled_albedo(
        improved_phong_sample, improved_phong_eval, params, wi, 100_000, seed, True
    )
    assert np.all(mean <= kd + ks + MC_SIGMAS * stderr + 1e-6), (mean, stderr, kd + ks)


@pytest.mark.parametrize(("g", "a"), [(1.0, 0.2), (10.0, 0.5), (3.0, 1.0)])
def test_improved_phong_under_uniform_light_can_exceed_unit_albedo(g, a) -> None:
    """The improved model is not reciprocal: its energy bound holds for a fixed light, not
    for a fixed viewer. At normal view the lobe integrated over light directions is
    N 2 pi / (g + 2 - a) = lobe_scale (g + 2) / (g + 2 - a) in closed form, which exceeds 1
    where the normalisation does not shrink the lobe (A_max = 1 at normal incidence)."""
    params = ImprovedPhongParams.from_values(0.0, 1.0, g, a, 0.0, 0.0)
    scale = float(_np(params.lobe_scale)[0])
    albedo = quadrature_albedo(improved_phong_eval, params, direction(0.0), 1.0, False)
    np.testing.assert_allclose(albedo, scale * (g + 2.0) / (g + 2.0 - a), rtol=1e-4)
    if g == 1.0:
        assert albedo[0] > 1.07


# --- normalisation of the improved lobe ----------------------------------------------------
def _brute_force_lobe_albedo(theta_i: float, g: float, a: float, b: float) -> float:
    """Midpoint rule on a dense (theta_o, phi_o) grid over the viewer hemisphere."""
    n_theta, n_phi = 300, 600
    theta = (np.arange(n_theta) + 0.5) * (0.5 * math.pi / n_theta)
    phi = (np.arange(n_phi) + 0.5) * (2.0 * math.pi / n_phi)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    r = np.array([-math.sin(theta_i), 0.0, math.cos(theta_i)])  # mirror of the light
    cos_beta = np.maximum(np.sin(t) * np.cos(p) * r[0] + np.cos(t) * r[2], 0.0)
    lobe = (g + 2.0) / (2.0 * math.pi) * cos_beta**g
    lobe *= np.exp(-b * (1.0 - cos_beta) ** (1.0 / math.pi))
    cell = (0.5 * math.pi / n_theta) * (2.0 * math.pi / n_phi)
    total = np.sum(lobe * np.cos(t) * np.sin(t)) * cell
    return float(total / max(math.cos(theta_i), MU_MIN) ** a)


LOBES = [(1.0, 0.5, 0.0), (10.0, 1.0, 0.0), (40.0, 0.3, 2.0), (5.0, 0.8, 0.5)]


@pytest.mark.parametrize(("g", "a", "b"), LOBES)
def test_lobe_albedo_matches_brute_force_integration(g, a, b) -> None:
    a_max, theta_max = improved_phong_max_lobe_albedo(g, a, b)
    for theta in (0.0, 0.7, 1.3, math.acos(MU_MIN), 1.56, theta_max):
        reference = _brute_force_lobe_albedo(theta, g, a, b)
        assert improved_phong_lobe_albedo(theta, g, a, b) == pytest.approx(
            reference, rel=BRUTE_FORCE_RTOL
        )
    assert a_max == pytest.approx(
        _brute_force_lobe_albedo(theta_max, g, a, b), rel=BRUTE_FORCE_RTOL
    )
    # No incidence angle of a grid over [0, 90) deg has a larger albedo.
    grid = np.linspace(0.0, math.radians(89.9), 30)
    assert max(_brute_force_lobe_albedo(t, g, a, b) for t in grid) <= a_max * (1 + BRUTE_FORCE_RTOL)


@pytest.mark.parametrize(("g", "a", "b"), LOBES)
def test_normalization_follows_its_definition(g, a, b) -> None:
    a_max, _ = improved_phong_max_lobe_albedo(g, a, b)
    expected = (g + 2.0) / (2.0 * math.pi) / max(1.0, a_max * 1.001)
    assert improved_phong_normalization(g, a, b) == pytest.approx(expected, rel=1e-12)
    if b == 0.0:
        assert a_max >= 1.0  # at normal incidence the b = 0 lobe has albedo 1


@pytest.mark.parametrize(("g", "b"), [(1.0, 0.0), (37.0, 3.0), (1e5, 0.0)])
def test_normalization_without_grazing_factor_is_phong(g, b) -> None:
    assert improved_phong_normalization(g, 0.0, b) == (g + 2.0) / (2.0 * math.pi)


@pytest.mark.parametrize(
    ("g", "a", "b"), [(10.0, 1.0, 0.0), (1e4, 1.0, 0.0), (3.0, 0.6, 0.0), (2.0, 1.0, 3.0)]
)
def test_normalised_lobe_reaches_unit_albedo_at_its_worst_angle(g, a, b) -> None:
    """The Dr.Jit lobe (ks = 1) at the angle of A_max reflects 1 / 1.001 of the light."""
    a_max, theta_max = improved_phong_max_lobe_albedo(g, a, b)
    assert a_max > 1.001
    params = ImprovedPhongParams.from_values(0.0, 1.0, g, a, b, 0.0)
    wi = direction(math.degrees(theta_max))
    albedo = quadrature_albedo(improved_phong_eval, params, wi, math.sqrt(2 / (g + 2)), True)
    np.testing.assert_allclose(albedo, 1.0 / 1.001, atol=QUADRATURE_ATOL)


# --- sampling ----------------------------------------------------------------------------------
CHI2_CASES_PARAMS = [
    # model, kd, ks, g, a, b, c, viewer theta (deg), seed
    ("phong", 0.3, 0.5, 20.0, 0.0, 0.0, 0.0, 30.0, 1),
    ("phong", 0.0, 0.8, 5.0, 0.0, 0.0, 0.0, 70.0, 2),  # lobe cut by the horizon
    ("phong", 0.1, 0.6, 200.0, 0.0, 0.0, 0.0, 85.0, 3),
    ("phong", 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 10.0, 4),  # diffuse only
    ("phong", (0.1, 0.2, 0.3), (0.3, 0.2, 0.1), 1.0, 0.0, 0.0, 0.0, 60.0, 5),
    ("improved", 0.2, 0.7, 50.0, 1.0, 2.0, 1.0, 45.0, 6),
    ("improved", 0.6, 0.3, 3.0, 0.5, 0.0, 2.0, 80.0, 7),
    ("improved", 0.0, 1.0, 1.0, 0.2, 0.0, 0.0, 0.0, 8),
]
assert len(CHI2_CASES_PARAMS) == CHI2_CASES


def _params(model, kd, ks, g, a, b, c):
    if model == "phong":
        return PhongParams.from_values(np.broadcast_to(kd, 3), np.broadcast_to(ks, 3), g)
    return ImprovedPhongParams.from_values(
        np.broadcast_to(kd, 3), np.broadcast_to(ks, 3), g, a, b, c
    )


def _functions(model):
    if model == "phong":
        return phong_sample, phong_pdf
    return improved_phong_sample, improved_phong_pdf


@pytest.mark.parametrize(
    ("model", "kd", "ks", "g", "a", "b", "c", "theta_deg", "seed"), CHI2_CASES_PARAMS
)
def test_sampler_follows_its_pdf(model, kd, ks, g, a, b, c, theta_deg, seed) -> None:
    params = _params(model, kd, ks, g, a, b, c)
    sample_fn, pdf_fn = _functions(model)
    wo = direction(theta_deg, 25.0)
    wi, pdf = sample_directions(sample_fn, params, wo, CHI2_SAMPLES, seed)
    valid = pdf > 0.0
    assert np.all(wi[valid, 2] > 0.0)
    result = chi2_direction_test(wi, valid, pdf_callable(pdf_fn, params, wo), sub=16)
    assert result.p_value > CHI2_SIGNIFICANCE, str(result)


@pytest.mark.parametrize("model", ["phong", "improved"])
def test_sample_returns_the_density_of_pdf(model) -> None:

    rng = np.random.default_rng(21)
    n = 20000
    wo = _random_directions(rng, n)
    kd, ks, g = _random_materials(rng, n)
    if model == "phong":
        params = PhongParams.from_values(kd, ks, g)
    else:
        g = rng.choice([1.0, 8.0, 60.0, 3000.0], n)  # a few lobes, each normalised once
        params = ImprovedPhongParams.from_values(kd, ks, g, 0.5, 1.0, 1.0)
    sample_fn, pdf_fn = _functions(model)
    check_sample_density_is_pdf(sample_fn, pdf_fn, params, wo, seed=21)


@pytest.mark.parametrize(
    ("kd", "ks", "g", "theta_deg"),
    [(0.2, 0.6, 30.0, 0.0), (0.2, 0.6, 30.0, 75.0), (0.0, 1.0, 2.0, 60.0), (0.0, 0.9, 1e3, 20.0)],
)
def test_pdf_integrates_to_the_probability_of_a_valid_sample(kd, ks, g, theta_deg) -> None:
    params = _params("phong", kd, ks, g, 0.0, 0.0, 0.0)
    wo = direction(theta_deg, 110.0)
    pdf = pdf_callable(phong_pdf, params, wo)
    width = math.sqrt(2.0 / (g + 2.0))
    integral = check_pdf_integral_is_valid_fraction(
        phong_sample, phong_pdf, params, wo, width, seed=31, atol=1e-4
    )
    # The lobe around the normal view lies entirely above the horizon.
    if theta_deg == 0.0:
        assert integral == pytest.approx(1.0, abs=1e-4)
    # A smooth check of the same integral on an independent (cos theta, phi) grid.
    if g <= 30.0:
        assert hemisphere_integral(pdf) == pytest.approx(integral, abs=1e-4)


# --- parameters ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kd": (0.5, 0.5, 0.5), "ks": (0.6, 0.1, 0.1), "g": 10.0}, "kd \\+ ks"),
        ({"kd": (-0.1, 0.5, 0.5), "ks": (0.1, 0.1, 0.1), "g": 10.0}, "kd must be in"),
        ({"kd": (0.1, 0.5, 0.5), "ks": (0.1, 1.5, 0.1), "g": 10.0}, "ks must be in"),
        ({"kd": (0.1, 0.1, 0.1), "ks": (0.1, 0.1, 0.1), "g": 0.5}, "gloss exponent"),
        ({"kd": (0.1, 0.1, 0.1), "ks": (0.1, 0.1, 0.1), "g": math.inf}, "gloss exponent"),
        ({"kd": (0.1, 0.1, 0.1), "ks": (0.1, 0.1, 0.1), "g": 2e5}, "gloss exponent"),
        ({"kd": (0.1, 0.1), "ks": (0.1, 0.1, 0.1), "g": 2.0}, "3 values"),
        ({"kd": np.full((4, 3), 0.1), "ks": (0.1, 0.1, 0.1), "g": [2.0, 3.0]}, "common length"),
    ],
)
def test_invalid_phong_parameters_are_rejected(kwargs, message) -> None:
    with pytest.raises(SatsightError, match=message):
        PhongParams.from_values(**kwargs)
    with pytest.raises(SatsightError, match=message):
        ImprovedPhongParams.from_values(**kwargs)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"a": 1.5}, "a must be in"),
        ({"a": -0.1}, "a must be in"),
        ({"b": -1.0}, "b must be"),
        ({"b": math.nan}, "b must be"),
        ({"c": -0.5}, "c must be"),
    ],
)
def test_invalid_improved_phong_parameters_are_rejected(extra, message) -> None:
    with pytest.raises(SatsightError, match=message):
        ImprovedPhongParams.from_values((0.2,) * 3, (0.3,) * 3, 10.0, **extra)


def test_parameters_broadcast_to_lanes() -> None:
    params = ImprovedPhongParams.from_values(
        np.full((5, 3), 0.2), (0.3, 0.3, 0.3), 10.0, a=[0, 0.1, 0.2, 0.3, 1.0]
    )
    assert _np(params.kd).shape == (5, 3)
    assert _np(params.g).shape == (5,)
    scale = _np(params.lobe_scale)
    assert scale[0] == 1.0
    assert np.all(np.diff(scale) <= 0.0)  # a stronger grazing factor needs a smaller N
