"""GGX metallic/roughness/IOR model: vector interface, masking options, sampling, energy.

The vector evaluation is checked against the cosine form used by the renderer and against
the formula written out in float64 numpy; the exact Smith masking against its closed form,
against the projected-area identity it satisfies and against Mitsuba's ``roughconductor``;
the sampler against its pdf with a chi-square test; the directional albedo (white furnace)
by importance-sampled Monte Carlo with a tolerance from the sample variance. The model is
not energy conserving for smooth dielectrics at grazing angles; the tests record by how much
(see the docstring of satsight.render.ggx).
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
    hemisphere_quadrature_around,
    importance_sampled_albedo,
    mirror,
    pdf_callable,
    quadrature_albedo,
    sample_directions,
)
from chi2_helpers import to_numpy as _np
from chi2_helpers import to_vector3f as _vec
from satsight.errors import SatsightError
from satsight.render.ggx import (
    MIN_GGX_ALPHA,
    GGXParams,
    ggx_diffuse_coefficient,
    ggx_diffuse_kernel,
    ggx_diffuse_probability,
    ggx_eval,
    ggx_eval_specular,
    ggx_metallic_brdf,
    ggx_pdf,
    ggx_sample,
    smith_ggx_g1,
)
from satsight.scene.materials import FIRST_MATERIALS

pytestmark = pytest.mark.usefixtures("llvm_variant")

FLOAT32_RTOL = 1e-4
MC_SIGMAS = 5.0  # one-sided Monte Carlo bound: a false alarm has probability 3e-7
MC_SAMPLES = 200_000
CHI2_CASES = 7  # chi-square tests in this file (Bonferroni-corrected significance)
CHI2_SIGNIFICANCE = 0.01 / CHI2_CASES
CHI2_SAMPLES = 200_000


# --- float64 reference (independent of satsight.render.ggx) ------------------------------------
def _fresnel_snell(cos_d: np.ndarray, ior: float) -> np.ndarray:
    """Unpolarised dielectric reflectance from Snell's law and the two polarisations."""
    if ior == 1.0:
        return np.zeros_like(cos_d)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_d**2)) / ior
    cos_t = np.sqrt(1.0 - sin_t**2)
    rs = ((cos_d - ior * cos_t) / (cos_d + ior * cos_t)) ** 2
    rp = ((ior * cos_d - cos_t) / (ior * cos_d + cos_t)) ** 2
    return 0.5 * (rs + rp)


def _g1_reference(cos_t: np.ndarray, roughness: float, masking: str) -> np.ndarray:
    alpha = max(roughness**2, MIN_GGX_ALPHA)
    if masking == "schlick":
        k = (roughness + 1.0) ** 2 / 8.0
        return cos_t / (cos_t * (1.0 - k) + k)
    tan2 = (1.0 - cos_t**2) / cos_t**2
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha**2 * tan2))


def _ggx_reference(wi, wo, base, metallic, roughness, ior, masking="schlick"):
    """f_r of the model in float64 for (n, 3) directions (both above the horizon)."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    ci, co, ch = wi[:, 2], wo[:, 2], h[:, 2]
    cd = np.sum(wi * h, axis=1)
    alpha = max(roughness**2, MIN_GGX_ALPHA)
    tan2_h = (1.0 - ch**2) / ch**2
    d = 1.0 / (math.pi * alpha**2 * ch**4 * (1.0 + tan2_h / alpha**2) ** 2)
    g = _g1_reference(ci, roughness, masking) * _g1_reference(co, roughness, masking)
    f_d = _fresnel_snell(cd, ior)
    base = np.asarray(base, dtype=np.float64)
    f_metal = base + (1.0 - base) * ((1.0 - cd) ** 5)[:, None]
    f = metallic * f_metal + (1.0 - metallic) * f_d[:, None]
    spec = f * (d * g / (4.0 * ci * co))[:, None]
    transmitted = (1.0 - _fresnel_snell(ci, ior)) * (1.0 - _fresnel_snell(co, ior))
    return (1.0 - metallic) * transmitted[:, None] * base / math.pi + spec


def _upper_directions(rng, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = np.abs(d[:, 2]) + 1e-3
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d.astype(np.float32).astype(np.float64)


# --- evaluation --------------------------------------------------------------------------------
@pytest.mark.parametrize("masking", ["schlick", "smith"])
def test_vector_eval_equals_the_cosine_form(masking) -> None:
    import mitsuba as mi

    rng = np.random.default_rng(41)
    n = 20000
    wi, wo = _upper_directions(rng, n), _upper_directions(rng, n)
    base = rng.uniform(0.0, 1.0, (n, 3))
    metallic = rng.uniform(0.0, 1.0, n)
    roughness = rng.uniform(0.2, 1.0, n)  # a >= 0.04, where the cosine form is accurate
    ior = rng.uniform(1.0, 3.0, n)
    params = GGXParams.from_values(base, metallic, roughness, ior, masking)
    f = _np(ggx_eval(_vec(wi), _vec(wo), params))
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    cos_h, cos_d = np.sum(h * [0, 0, 1.0], axis=1), np.sum(wi * h, axis=1)
    expected = ggx_metallic_brdf(
        mi.Float(wi[:, 2].astype(np.float32)),
        mi.Float(wo[:, 2].astype(np.float32)),
        mi.Float(cos_h.astype(np.float32)),
        mi.Float(cos_d.astype(np.float32)),
        params.base,
        params.metallic,
        params.roughness,
        params.ior,
        masking=masking,
    )
    np.testing.assert_allclose(f, _np(expected), rtol=2e-3, atol=1e-6)


def test_cosine_form_defaults_to_the_schlick_masking() -> None:
    import mitsuba as mi

    args = [mi.Float(0.8), mi.Float(0.5), mi.Float(0.95), mi.Float(0.9), mi.Color3f(0.5)]
    args += [mi.Float(0.3), mi.Float(0.4), mi.Float(1.5)]
    default = _np(ggx_metallic_brdf(*args))
    assert np.array_equal(default, _np(ggx_metallic_brdf(*args, masking="schlick")))
    assert not np.allclose(default, _np(ggx_metallic_brdf(*args, masking="smith")))
    assert GGXParams.from_values((0.5,) * 3, 0.3, 0.4, 1.5).masking == "schlick"


@pytest.mark.parametrize("masking", ["schlick", "smith"])
@pytest.mark.parametrize(
    ("sun_deg", "view_deg", "azimuth_deg", "metallic", "roughness", "ior"),
    [
        (30.0, 30.0, 180.0, 1.0, 0.3, 1.5),
        (10.0, 50.0, 90.0, 0.0, 0.5, 1.5),
        (60.0, 20.0, 150.0, 0.5, 0.7, 2.0),
        (45.0, 44.0, 180.0, 1.0, 0.15, 1.5),
        (80.0, 75.0, 170.0, 0.2, 0.05, 1.33),
        (0.0, 0.0, 0.0, 0.0, 1.0, 1.0),
    ],
)
def test_vector_eval_matches_float64_formula(
    masking, sun_deg, view_deg, azimuth_deg, metallic, roughness, ior
) -> None:
    base = np.array([0.9, 0.6, 0.3])
    wi = direction(sun_deg)[None, :]
    wo = direction(view_deg, azimuth_deg)[None, :]
    wi, wo = (v.astype(np.float32).astype(np.float64) for v in (wi, wo))
    params = GGXParams.from_values(base, metallic, roughness, ior, masking)
    f = _np(ggx_eval(_vec(wi), _vec(wo), params))
    expected = _ggx_reference(wi, wo, base, metallic, roughness, ior, masking)
    np.testing.assert_allclose(f, expected, rtol=FLOAT32_RTOL)


def test_vector_eval_keeps_its_precision_for_the_narrowest_lobe() -> None:
    """At a = MIN_GGX_ALPHA, directions within a few a of the mirror direction."""
    rng = np.random.default_rng(42)
    n = 2000
    wo = np.broadcast_to(direction(35.0), (n, 3))
    offsets = rng.normal(scale=2e-3, size=(n, 3))
    wi = mirror(direction(35.0)) + offsets
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wi = wi.astype(np.float32).astype(np.float64)
    wo = wo.astype(np.float32).astype(np.float64)
    params = GGXParams.from_values((1.0, 1.0, 1.0), 1.0, 0.0, 1.5)
    f = _np(ggx_eval(_vec(wi), _vec(wo), params))
    expected = _ggx_reference(wi, wo, (1.0, 1.0, 1.0), 1.0, 0.0, 1.5)
    np.testing.assert_allclose(f, expected, rtol=2e-3)


@pytest.mark.parametrize("masking", ["schlick", "smith"])
def test_eval_is_non_negative_finite_and_zero_below_the_horizon(masking) -> None:
    rng = np.random.default_rng(43)
    n = 20000
    wi = rng.normal(size=(n, 3))
    wo = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi[:20, 2] = 0.0
    wo[:20] = -wi[:20]  # wi + wo = 0: no half vector
    params = GGXParams.from_values(
        rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, n), rng.uniform(0, 1, n), 1.5, masking
    )
    f = _np(ggx_eval(_vec(wi), _vec(wo), params))
    spec = _np(ggx_eval_specular(_vec(wi), _vec(wo), params))
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(spec))
    assert np.all(f >= 0.0) and np.all(spec >= 0.0) and np.all(spec <= f * (1 + 1e-6) + 1e-12)
    below = (wi[:, 2] <= 0.0) | (wo[:, 2] <= 0.0)
    assert np.all(f[below] == 0.0)
    assert np.all(f[~below] > 0.0)


def test_diffuse_part_is_coefficient_times_zonal_kernel() -> None:
    """pi f_diffuse(wi, wo) cos(theta_i) = kd_eq(wo) * k(cos theta_i) for random directions,
    with kd_eq from ``ggx_diffuse_coefficient`` and k = ``ggx_diffuse_kernel(ior)``."""
    rng = np.random.default_rng(44)
    n = 1000
    wi, wo = _upper_directions(rng, n), _upper_directions(rng, n)
    base, metallic = rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, n)
    ior = 1.45
    params = GGXParams.from_values(base, metallic, rng.uniform(0, 1, n), ior)
    kd_eq, exponent = ggx_diffuse_coefficient(params, _vec(wo))
    expected_kd = (1.0 - metallic)[:, None] * (1.0 - _fresnel_snell(wo[:, 2], ior))[:, None] * base
    np.testing.assert_allclose(_np(kd_eq), expected_kd, rtol=1e-4, atol=1e-6)
    assert np.all(_np(exponent) == 0.0)
    diffuse = _np(ggx_eval(_vec(wi), _vec(wo), params)) - _np(
        ggx_eval_specular(_vec(wi), _vec(wo), params)
    )
    kernel = ggx_diffuse_kernel(ior)(wi[:, 2])
    np.testing.assert_allclose(
        math.pi * diffuse * wi[:, 2:3], _np(kd_eq) * kernel[:, None], rtol=2e-4, atol=1e-6
    )


# --- Smith masking ---------------------------------------------------------------------------
@pytest.mark.parametrize("alpha", [MIN_GGX_ALPHA, 0.05, 0.3, 0.7, 1.0])
def test_smith_g1_matches_its_closed_form(alpha) -> None:
    import mitsuba as mi

    theta = np.linspace(0.0, math.radians(89.9), 200)
    cos_t = np.cos(theta)
    g1 = _np(smith_ggx_g1(mi.Float(cos_t.astype(np.float32)), mi.Float(alpha)))
    expected = 2.0 / (1.0 + np.sqrt(1.0 + alpha**2 * np.tan(theta) ** 2))
    np.testing.assert_allclose(g1, expected, rtol=1e-5)
    assert g1[0] == pytest.approx(1.0, abs=1e-7)  # no masking at normal incidence
    assert np.all(np.diff(g1) <= 1e-7)  # decreasing towards grazing
    assert _np(smith_ggx_g1(mi.Float(0.0, -0.5), mi.Float(alpha))).tolist() == [0.0, 0.0]


@pytest.mark.parametrize("alpha", [0.1, 0.4, 1.0])
@pytest.mark.parametrize("theta_deg", [0.0, 40.0, 75.0])
def test_smith_g1_satisfies_the_projected_area_identity(alpha, theta_deg) -> None:
    """G1(v) integral of max(v.h, 0) D(h) d omega_h = cos(theta_v) (Heitz 2014, "Understanding
    the masking-shadowing function in microfacet-based BRDFs", Eq. 18), with D integrated in
    float64 on a rule centred on the normal."""
    import mitsuba as mi

    v = direction(theta_deg, 30.0)
    h, weights = hemisphere_quadrature_around(np.array([0.0, 0.0, 1.0]), alpha, n_phi=192)
    d = alpha**2 / (math.pi * (h[:, 2] ** 2 * (alpha**2 - 1.0) + 1.0) ** 2)
    projected = float(np.dot(np.maximum(h @ v, 0.0) * d, weights))
    g1 = float(_np(smith_ggx_g1(mi.Float(v[2]), mi.Float(alpha)))[0])
    assert g1 * projected == pytest.approx(v[2], rel=1e-4)


@pytest.mark.parametrize("roughness", [0.1, 0.3, 0.6, 1.0])
def test_smith_option_matches_mitsuba_roughconductor(roughness) -> None:
    """A metal of base colour 1 (Schlick F = 1) with Smith masking is Mitsuba's GGX conductor
    with alpha = R^2 and ``material="none"`` (F = 1). Mitsuba's eval includes cos(theta_i)."""
    import drjit as dr
    import mitsuba as mi

    rng = np.random.default_rng(45)
    n = 5000
    wi, wo = _upper_directions(rng, n), _upper_directions(rng, n)
    bsdf = mi.load_dict(
        {"type": "roughconductor", "distribution": "ggx", "alpha": roughness**2, "material": "none"}
    )
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = _vec(wo)  # Mitsuba's wi is the direction the path arrived from: the viewer
    reference = _np(bsdf.eval(mi.BSDFContext(), si, _vec(wi))) / wi[:, 2:3]
    params = GGXParams.from_values((1.0, 1.0, 1.0), 1.0, roughness, 1.5, masking="smith")
    f = _np(ggx_eval(_vec(wi), _vec(wo), params))
    np.testing.assert_allclose(f, reference, rtol=2e-4, atol=1e-6)


# --- sampling ----------------------------------------------------------------------------------
CHI2_CASES_PARAMS = [
    # base, metallic, roughness, ior, masking, viewer theta (deg), seed
    ((0.8, 0.5, 0.2), 0.0, 0.5, 1.5, "schlick", 30.0, 1),
    ((0.9, 0.9, 0.9), 1.0, 0.3, 1.5, "smith", 60.0, 2),
    ((0.5, 0.5, 0.5), 0.5, 0.8, 1.5, "schlick", 80.0, 3),
    ((0.5, 0.5, 0.5), 0.0, 1.0, 1.0, "schlick", 40.0, 4),  # Lambert: diffuse only
    ((0.9, 0.9, 0.9), 1.0, 0.4, 1.5, "schlick", 75.0, 5),
    ((0.05, 0.07, 0.2), 0.0, 0.35, 1.52, "schlick", 0.0, 6),  # mostly specular choice
    ((0.3, 0.3, 0.3), 0.2, 1.0, 3.0, "smith", 88.0, 7),
]
assert len(CHI2_CASES_PARAMS) == CHI2_CASES


@pytest.mark.parametrize(
    ("base", "metallic", "roughness", "ior", "masking", "theta_deg", "seed"), CHI2_CASES_PARAMS
)
def test_sampler_follows_its_pdf(base, metallic, roughness, ior, masking, theta_deg, seed) -> None:
    params = GGXParams.from_values(base, metallic, roughness, ior, masking)
    wo = direction(theta_deg, -50.0)
    wi, pdf = sample_directions(ggx_sample, params, wo, CHI2_SAMPLES, seed)
    valid = pdf > 0.0
    assert np.all(wi[valid, 2] > 0.0)
    result = chi2_direction_test(wi, valid, pdf_callable(ggx_pdf, params, wo), sub=16)
    assert result.p_value > CHI2_SIGNIFICANCE, str(result)


def test_sample_returns_the_density_of_pdf() -> None:

    rng = np.random.default_rng(46)
    n = 20000
    wo = rng.normal(size=(n, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    params = GGXParams.from_values(
        rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, n), rng.uniform(0, 1, n), 1.5
    )
    check_sample_density_is_pdf(ggx_sample, ggx_pdf, params, wo, seed=46)


@pytest.mark.parametrize(
    ("metallic", "roughness", "theta_deg"), [(1.0, 0.3, 0.0), (1.0, 0.6, 70.0), (0.3, 0.9, 85.0)]
)
def test_pdf_integrates_to_the_probability_of_a_valid_sample(metallic, roughness, theta_deg):
    params = GGXParams.from_values((0.7, 0.7, 0.7), metallic, roughness, 1.5)
    wo = direction(theta_deg, 20.0)
    integral = check_pdf_integral_is_valid_fraction(
        ggx_sample, ggx_pdf, params, wo, 2.0 * roughness**2, seed=47, atol=2e-4, n_phi=128
    )
    if theta_deg == 0.0:
        # Metal at normal view: the sample is lost when theta_h > 45 deg, which the GGX
        # slope distribution gives with probability a^2 / (1 + a^2).
        alpha2 = roughness**4
        assert integral == pytest.approx(1.0 - alpha2 / (1.0 + alpha2), abs=2e-4)


def test_diffuse_probability_follows_the_lobe_weights() -> None:
    params = GGXParams.from_values(
        np.array([[0.5] * 3, [0.5] * 3, [0.0] * 3, [0.5] * 3, [0.05, 0.07, 0.2]]),
        [1.0, 0.0, 0.0, 0.0, 0.0],
        0.5,
        [1.5, 1.0, 1.0, 1.5, 1.52],
    )
    p = _np(ggx_diffuse_probability(params))
    assert p[0] == 0.0  # metal: no diffuse part
    assert p[1] == 1.0  # IOR 1 dielectric: no specular part
    assert p[2] == 1.0  # nothing reflects; either choice is valid
    w_d, w_s = 0.5 * (1.0 - 0.04), 0.04
    assert p[3] == pytest.approx(w_d / (w_d + w_s), rel=1e-6)
    assert 0.05 <= p[4] <= 0.95


# --- energy (white furnace) ------------------------------------------------------------------
def _albedo(params, theta_deg: float, seed: int):
    wo = direction(theta_deg, 15.0)
    return importance_sampled_albedo(ggx_sample, ggx_eval, params, wo, MC_SAMPLES, seed, False)


@settings(max_examples=20, deadline=None, derandomize=True)
@given(
    base=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
    roughness=st.floats(0.0, 1.0),
    masking=st.sampled_from(["schlick", "smith"]),
    theta_deg=st.floats(0.0, 89.9),
    seed=st.integers(0, 2**31),
)
def test_metals_conserve_energy(base, roughness, masking, theta_deg, seed) -> None:
    """M = 1: the albedo stays <= 1 for both maskings (Schlick's F <= 1, G <= Smith's G)."""
    params = GGXParams.from_values(base, 1.0, roughness, 1.5, masking)
    mean, stderr = _albedo(params, theta_deg, seed)
    assert np.all(mean <= 1.0 + MC_SIGMAS * stderr + 1e-6), (mean, stderr)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    base=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
    metallic=st.floats(0.0, 1.0),
    roughness=st.floats(0.0, 1.0),
    ior=st.floats(1.0, 4.0),
    masking=st.sampled_from(["schlick", "smith"]),
    theta_deg=st.floats(0.0, 89.9),
    seed=st.integers(0, 2**31),
)
def test_albedo_is_at_most_one(base, metallic, roughness, ior, masking, theta_deg, seed) -> None:
    """White furnace over the whole parameter range: the model reflects at most what it
    receives (the diffuse part carries the transmittance of both interface crossings)."""
    params = GGXParams.from_values(base, metallic, roughness, ior, masking)
    mean, stderr = _albedo(params, theta_deg, seed)
    assert np.all(mean <= 1.0 + MC_SIGMAS * stderr + 1e-4), (mean, stderr)


@pytest.mark.parametrize(
    ("masking", "ior", "theta_deg"),
    [("schlick", 1.31, 80.6), ("smith", 1.13, 89.7), ("schlick", 1.5, 0.0)],
)
def test_smooth_white_dielectric_conserves_energy_at_grazing_view(masking, ior, theta_deg):
    """The worst cases of a single 1 - F_d(wi.h) diffuse weight (albedo 1.098 and 1.91
    there) stay <= 1 with the two-crossing weight, by quadrature."""
    params = GGXParams.from_values((1.0, 1.0, 1.0), 0.0, 0.0, ior, masking)
    mean, stderr = _albedo(params, theta_deg, seed=48)
    assert mean[0] <= 1.0 + MC_SIGMAS * stderr[0] + 1e-4, (mean, stderr)


def test_rough_dielectric_and_library_materials_conserve_energy() -> None:
    """R = 1 (the Schlick and Smith masking coincide) conserves energy, and so do the
    materials of the first library (none is a smooth, bright dielectric)."""
    params = GGXParams.from_values((1.0, 1.0, 1.0), 0.0, 1.0, 1.5)
    for theta_deg in (0.0, 60.0, 85.0):
        albedo = quadrature_albedo(ggx_eval, params, direction(theta_deg), 2.0, False)
        assert np.all(albedo <= 1.0 + 1e-4)
    for material in FIRST_MATERIALS.values():
        params = GGXParams.from_material(material)
        for theta_deg in (0.0, 45.0, 75.0, 85.0):
            wo = direction(theta_deg)
            mean, stderr = importance_sampled_albedo(
                ggx_sample, ggx_eval, params, wo, 50_000, 49, False
            )
            assert np.all(mean <= 1.0 + MC_SIGMAS * stderr + 1e-6), (material.name, mean)


# --- parameters ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "message"),
    [
        (((1.2, 0.5, 0.5), 0.5, 0.5, 1.5), "base colour"),
        (((0.5, 0.5), 0.5, 0.5, 1.5), "base colour"),
        (((0.5,) * 3, 1.5, 0.5, 1.5), "metallic"),
        (((0.5,) * 3, 0.5, -0.1, 1.5), "roughness"),
        (((0.5,) * 3, 0.5, 0.5, 0.9), "ior"),
        (((0.5,) * 3, 0.5, 0.5, math.inf), "ior"),
    ],
)
def test_invalid_parameters_are_rejected(args, message) -> None:
    with pytest.raises(SatsightError, match=message):
        GGXParams.from_values(*args)


def test_unknown_masking_is_rejected() -> None:
    with pytest.raises(SatsightError, match="masking"):
        GGXParams.from_values((0.5,) * 3, 0.5, 0.5, 1.5, masking="beckmann")


def test_parameters_from_a_material() -> None:
    material = FIRST_MATERIALS["mli_gold"]
    params = GGXParams.from_material(material, masking="smith")
    np.testing.assert_allclose(_np(params.base)[0], material.base_color_rgb, rtol=1e-7)
    assert _np(params.roughness)[0] == pytest.approx(material.roughness)
    assert params.masking == "smith"
