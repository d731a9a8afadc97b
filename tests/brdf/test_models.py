"""The numpy reflection models used for fitting are the renderer's Dr.Jit models.

The Dr.Jit functions of ``satsight.render.phong`` and ``satsight.render.ggx`` are generic
over the array type, so they are evaluated here in float64 (``Array3f64``, ``Float64``) on
directions that are exact in float32 (the mirror helper builds a float32 vector): the two
implementations must then agree to 1e-6 relative. A second check runs the renderer's
float32 path as it renders. The Fresnel term and the albedo quadrature are checked against
closed forms.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.brdf.models import (
    directional_albedo,
    fresnel_dielectric_unpolarised,
    ggx_brdf,
    ggx_lobe_width_rad,
    improved_phong_brdf,
    phong_brdf,
    phong_lobe_width_rad,
    unit_vectors_from_angles,
)

pytestmark = pytest.mark.usefixtures("llvm_variant")

FLOAT64_RTOL = 1e-6  # the brief's bound; observed ~1e-13, 1e-7 where the renderer's
# exponent 1/pi is a float32 constant (improved Phong)
FLOAT32_RTOL = 2e-4  # the renderer's float32 arithmetic, lobes with g <= 100
QUADRATURE_ATOL = 3e-4  # ``directional_albedo`` with 256 azimuth nodes (horizon kink)

KD = np.array([0.25, 0.35, 0.10])
KS = np.array([0.55, 0.30, 0.05])
BASE = np.array([0.9, 0.6, 0.3])


def _directions(seed: int, n: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """Random pairs on the upper hemisphere, half of them close to the mirror geometry
    (where the lobes peak), rounded to float32."""
    rng = np.random.default_rng(seed)

    def unit(v):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    wi = unit(rng.normal(size=(n, 3)))
    wi[:, 2] = np.abs(wi[:, 2])
    wo = unit(rng.normal(size=(n, 3)))
    wo[:, 2] = np.abs(wo[:, 2])
    near = n // 2
    wo[:near] = unit(wi[:near] * [-1.0, -1.0, 1.0] + 0.05 * rng.normal(size=(near, 3)))
    return wi.astype(np.float32).astype(np.float64), wo.astype(np.float32).astype(np.float64)


def _rel_error(a: np.ndarray, b: np.ndarray) -> float:
    scale = np.maximum(np.abs(b), 1e-12 * np.max(np.abs(b)))
    return float(np.max(np.abs(a - b) / scale))


def _lobe_representable(wi: np.ndarray, wo: np.ndarray, g: float) -> np.ndarray:
    """Rows where cos^g(beta) stays above 1e-280: Dr.Jit's float64 power, exp2(g log2 x),
    returns -inf instead of 0 or a subnormal near the float64 underflow threshold
    (cos(beta) = 0.17, g = 400). The renderer runs in float32, where it underflows to 0."""
    cos_beta = np.maximum(np.sum(wi * wo * [-1.0, -1.0, 1.0], axis=1), 0.0)
    with np.errstate(divide="ignore"):
        return (cos_beta == 0.0) | (g * np.log10(cos_beta) > -280.0)


def _dr64():
    from drjit.llvm.ad import Array3f64, Float64

    return Array3f64, Float64


def _rgb64(values):
    array3, _ = _dr64()
    return array3(np.asarray(values, dtype=np.float64).reshape(3, 1))


def _vec64(v: np.ndarray):
    array3, _ = _dr64()
    return array3(np.ascontiguousarray(v.T))


@pytest.mark.parametrize("g", [1.0, 20.0, 500.0])
def test_phong_equals_renderer_in_float64(g):
    from satsight.render.phong import PhongParams, phong_eval

    _, f64 = _dr64()
    wi, wo = _directions(1)
    ref = np.array(phong_eval(_vec64(wi), _vec64(wo), PhongParams(_rgb64(KD), _rgb64(KS), f64(g))))
    ours = phong_brdf(wi[:, None, :], wo[:, None, :], KD, KS, g)
    keep = _lobe_representable(wi, wo, g)
    assert np.count_nonzero(keep) > 0.85 * keep.size
    assert _rel_error(ours[keep], ref.T[keep]) < FLOAT64_RTOL


@pytest.mark.parametrize(
    ("g", "a", "b", "c"),
    [(1.0, 0.3, 0.7, 1.0), (20.0, 0.0, 0.0, 0.0), (20.0, 1.0, 5.0, 3.0), (400.0, 0.5, 0.2, 0.5)],
)
def test_improved_phong_equals_renderer_in_float64(g, a, b, c):
    from satsight.render.phong import (
        ImprovedPhongParams,
        improved_phong_eval,
        improved_phong_lobe_scale,
    )

    _, f64 = _dr64()
    wi, wo = _directions(2)
    params = ImprovedPhongParams(
        _rgb64(KD),
        _rgb64(KS),
        f64(g),
        f64(a),
        f64(b),
        f64(c),
        f64(improved_phong_lobe_scale(g, a, b)),
    )
    ref = np.array(improved_phong_eval(_vec64(wi), _vec64(wo), params))
    ours = improved_phong_brdf(wi[:, None, :], wo[:, None, :], KD, KS, g, a, b, c)
    keep = _lobe_representable(wi, wo, g)
    assert np.count_nonzero(keep) > 0.85 * keep.size
    assert _rel_error(ours[keep], ref.T[keep]) < FLOAT64_RTOL


@pytest.mark.parametrize("masking", ["schlick", "smith"])
@pytest.mark.parametrize(
    ("metallic", "roughness", "ior"),
    [(0.0, 0.5, 1.5), (1.0, 0.1, 1.5), (0.4, 0.04, 2.5), (0.2, 0.9, 1.0), (0.7, 0.3, 3.9)],
)
def test_ggx_equals_renderer_in_float64(metallic, roughness, ior, masking):
    from satsight.render.ggx import GGXParams, ggx_eval

    _, f64 = _dr64()
    wi, wo = _directions(3)
    params = GGXParams(_rgb64(BASE), f64(metallic), f64(roughness), f64(ior), masking)
    ref = np.array(ggx_eval(_vec64(wi), _vec64(wo), params))
    ours = ggx_brdf(wi[:, None, :], wo[:, None, :], BASE, metallic, roughness, ior, masking)
    assert _rel_error(ours, ref.T) < FLOAT64_RTOL


def test_models_equal_renderer_float32_path():
    """The renderer's own float32 parameter containers and vectors, as it renders."""
    import mitsuba as mi

    from satsight.render.ggx import GGXParams, ggx_eval
    from satsight.render.phong import ImprovedPhongParams, improved_phong_eval

    wi, wo = _directions(4, 2000)
    wi32 = mi.Vector3f(np.ascontiguousarray(wi.T, dtype=np.float32))
    wo32 = mi.Vector3f(np.ascontiguousarray(wo.T, dtype=np.float32))
    params = ImprovedPhongParams.from_values(KD, KS, 60.0, 0.4, 0.6, 1.0)
    ref = np.array(improved_phong_eval(wi32, wo32, params)).T
    ours = improved_phong_brdf(wi[:, None, :], wo[:, None, :], KD, KS, 60.0, 0.4, 0.6, 1.0)
    np.testing.assert_allclose(ours, ref, rtol=FLOAT32_RTOL, atol=1e-6 * ref.max())
    ggx_params = GGXParams.from_values(BASE, 0.3, 0.4, 1.6)
    ref = np.array(ggx_eval(wi32, wo32, ggx_params)).T
    ours = ggx_brdf(wi[:, None, :], wo[:, None, :], BASE, 0.3, 0.4, 1.6)
    np.testing.assert_allclose(ours, ref, rtol=FLOAT32_RTOL, atol=1e-6 * ref.max())


def test_improved_phong_with_a_b_c_zero_is_phong():
    wi, wo = _directions(5)
    np.testing.assert_array_equal(
        improved_phong_brdf(wi, wo, 0.3, 0.6, 35.0, 0.0, 0.0, 0.0),
        phong_brdf(wi, wo, 0.3, 0.6, 35.0),
    )


def test_zero_below_the_horizon():
    wi = unit_vectors_from_angles(np.radians([30.0, 95.0]), 0.0)
    wo = unit_vectors_from_angles(np.radians([100.0, 30.0]), math.pi)
    assert np.all(phong_brdf(wi, wo, 0.5, 0.5, 10.0) == 0.0)
    assert np.all(improved_phong_brdf(wi, wo, 0.5, 0.5, 10.0, 0.5, 0.5, 1.0) == 0.0)
    assert np.all(ggx_brdf(wi, wo, 0.5, 0.5, 0.5, 1.5) == 0.0)


def test_fresnel_closed_forms():
    """n = 1.5: F0 = 0.04; Brewster's angle (p-polarised reflectance 0) gives
    R = R_s / 2 with R_s = sin^2(theta_i - theta_t) (Born & Wolf); grazing gives 1."""
    n = 1.5
    assert fresnel_dielectric_unpolarised(1.0, n) == pytest.approx(0.04, rel=1e-12)
    brewster = math.atan(n)
    theta_t = math.asin(math.sin(brewster) / n)
    expected = 0.5 * math.sin(brewster - theta_t) ** 2
    assert fresnel_dielectric_unpolarised(math.cos(brewster), n) == pytest.approx(expected)
    assert fresnel_dielectric_unpolarised(0.0, n) == pytest.approx(1.0)
    assert fresnel_dielectric_unpolarised(0.5, 1.0) == 0.0


def test_directional_albedo_closed_forms():
    """Lambert: A = kd at every incidence; normalised Phong at normal incidence: kd + ks."""
    for theta in (0.0, 0.7, 1.3):
        value = directional_albedo(lambda wi, wo: phong_brdf(wi, wo, 0.8, 0.0, 1.0), theta)
        assert value == pytest.approx(0.8, abs=QUADRATURE_ATOL)
    for g in (5.0, 200.0, 5000.0):
        value = directional_albedo(
            lambda wi, wo, g=g: phong_brdf(wi, wo, 0.3, 0.7, g), 0.0, phong_lobe_width_rad(g)
        )
        assert value == pytest.approx(1.0, abs=QUADRATURE_ATOL)


def test_directional_albedo_of_white_metal_below_one():
    """A white GGX metal with exact Smith masking loses energy (single scattering) but never
    gains: 0 < A <= 1, and near 1 for a smooth one."""
    for roughness in (0.1, 0.5, 0.9):
        for theta in (0.0, 0.8, 1.4):
            value = directional_albedo(
                lambda wi, wo, r=roughness: ggx_brdf(wi, wo, 1.0, 1.0, r, 1.5, "smith"),
                theta,
                ggx_lobe_width_rad(roughness),
            )
            assert 0.0 < value <= 1.0 + QUADRATURE_ATOL
    smooth = directional_albedo(
        lambda wi, wo: ggx_brdf(wi, wo, 1.0, 1.0, 0.1, 1.5, "smith"), 0.0, ggx_lobe_width_rad(0.1)
    )
    assert smooth > 0.99


def test_channel_broadcasting():
    wi, wo = _directions(6, 50)
    per_channel = phong_brdf(wi[:, None, :], wo[:, None, :], KD, KS, 12.0)
    assert per_channel.shape == (50, 3)
    for k in range(3):
        np.testing.assert_array_equal(per_channel[:, k], phong_brdf(wi, wo, KD[k], KS[k], 12.0))
