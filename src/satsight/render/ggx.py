"""The metallic / roughness / IOR GGX reflection model of the paper (Eq. 18-20), in Dr.Jit.

The functions take Dr.Jit arrays (any backend): ``ggx_metallic_brdf`` the cosines between
unit vectors in the shading frame, the vector interface below the directions themselves.
They return the BRDF value f_r in sr^-1, so that reflected radiance is
``L_r = f_r * E * cos(theta_i)`` for a collimated source of irradiance E (W m^-2).

Model (reading of Eq. 18-20 recorded in docs/design.md)::

    f_r = (1 - M) * base * (1 - F_d(n.wi)) (1 - F_d(n.wo)) / pi       diffuse
        + F(h.wi) * D(n.h) * G(n.wi) G(n.wo) / (4 (n.wi) (n.wo))       specular

    F   = M * Schlick(base, h.wi) + (1 - M) * F_d(h.wi)   -> ks = M base + (1 - M) F0 at 0 deg
    F_d = exact unpolarised Fresnel reflectance of a dielectric of index IOR (F_d = 0 at IOR 1)
    D   = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2),  a = R^2         (GGX / Trowbridge-Reitz)
    G   = x / (x (1 - k) + k),  k = (R + 1)^2 / 8                (Schlick-GGX, Smith form)

Masking options (``masking=``): ``"schlick"``, the paper's Schlick-GGX above (default), and
``"smith"``, the exact separable Smith masking of GGX,
G1(v) = 2 / (1 + sqrt(1 + a^2 tan^2 theta_v)) (Walter et al. 2007, "Microfacet models for
refraction through rough surfaces", Eq. 34). With ``"smith"``, a metal of base colour 1
(Schlick's F = 1) is the GGX conductor of Mitsuba's ``roughconductor`` (alpha = R^2,
``material="none"``), against which the renderer can be compared.

Vector interface (frame and direction conventions of ``satsight.render.sampling``: local
shading frame with normal +z, wi towards the light, wo towards the viewer): ``GGXParams``
holds one value per lane, ``ggx_eval`` / ``ggx_eval_specular`` evaluate f_r, ``ggx_sample``
draws wi from a mixture of a cosine-weighted diffuse lobe and GGX half-vector sampling
(Walter et al. 2007, Eq. 35-36: pdf(h) = D(h) cos(theta_h), pdf(wi) = pdf(h) / (4 |wo.h|)),
and ``ggx_pdf`` is that mixture's density.

Diffuse weight: light enters the diffuse layer through the dielectric interface and
leaves through it again, so the diffuse part carries the transmittance of both crossings,
(1 - F_d(n.wi)) (1 - F_d(n.wo)), which keeps the BRDF reciprocal. A single factor
1 - F_d(wi.h) (the half-vector angle) would not conserve energy: it stays near 1 - F0 for
most light directions even where the viewer sees strong specular reflection at grazing
incidence, and the directional albedo of a white smooth dielectric then reaches 1.098 with
Schlick-GGX masking (M = 0, IOR 1.31, theta_o = 80.6 deg) and 1.91 with Smith masking
(float64 quadrature). With the two-crossing weight the albedo stays <= 1 over the whole
parameter range (tests/render/test_ggx_sampling.py, white furnace).

Precision: ``ggx_distribution`` takes cos(theta_h), and 1 - cos^2 loses precision in float32
for the narrowest lobes (several per cent near the peak at a = 1e-3). The vector functions
evaluate D from the half vector itself (``ggx_distribution_h``) and keep their precision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from satsight.errors import SatsightError
from satsight.render.sampling import (
    TWO_PI,
    cosine_hemisphere_pdf,
    reflect,
    square_to_cosine_hemisphere,
)

INV_PI = 1.0 / math.pi
# Lower bound of the GGX width a = R^2 so that a perfectly smooth setting stays finite
# in float32 (peak D = 1 / (pi a^2)).
MIN_GGX_ALPHA = 1e-3
MASKING_MODELS = ("schlick", "smith")
# Bounds of the probability of sampling the diffuse lobe when both lobes carry light.
MIN_LOBE_PROBABILITY = 0.05


def fresnel_dielectric(cos_theta, ior):
    """Unpolarised Fresnel reflectance for light arriving from vacuum on a dielectric.

    cos_theta: cosine of the angle of incidence (to the microfacet normal), in [0, 1].
    ior: real index of refraction >= 1. Exact (Born & Wolf) form; equals
    ((n - 1) / (n + 1))^2 at normal incidence and 0 for n = 1.
    """
    c = dr.clip(cos_theta, 0.0, 1.0)
    g = dr.sqrt(dr.maximum(ior * ior - 1.0 + c * c, 0.0))
    a = (g - c) / dr.maximum(g + c, 1e-12)
    b = (c * (g + c) - 1.0) / dr.maximum(c * (g - c) + 1.0, 1e-12)
    f = 0.5 * a * a * (1.0 + b * b)
    return dr.select(ior > 1.0, f, 0.0)


def fresnel_schlick(f0, cos_theta):
    """Schlick's approximation F0 + (1 - F0)(1 - cos)^5 (per colour channel for metals)."""
    m = 1.0 - dr.clip(cos_theta, 0.0, 1.0)
    m2 = m * m
    return f0 + (1.0 - f0) * (m2 * m2 * m)


def ggx_distribution(cos_h, alpha):
    """GGX normal distribution D(h) in sr^-1 for the half-vector cosine n.h (paper Eq. 19)."""
    a2 = alpha * alpha
    t = cos_h * cos_h * (a2 - 1.0) + 1.0
    return a2 * INV_PI / dr.maximum(t * t, 1e-30)


def schlick_ggx_g1(cos_theta, roughness):
    """Schlick-GGX masking term with k = (R + 1)^2 / 8 (paper Eq. 20)."""
    k = (roughness + 1.0) * (roughness + 1.0) * 0.125
    c = dr.maximum(cos_theta, 0.0)
    return c / (c * (1.0 - k) + k)


def smith_ggx_g1(cos_theta, alpha):
    """Exact Smith masking of GGX, G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta)).

    Written as 2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)) with c = cos(theta), which is
    finite at grazing angles (G1 -> 0) and exactly 1 at normal incidence. Walter et al.
    2007, "Microfacet models for refraction through rough surfaces", Eq. 34.
    """
    c = dr.maximum(cos_theta, 0.0)
    a2 = alpha * alpha
    return 2.0 * c / dr.maximum(c + dr.sqrt(a2 + (1.0 - a2) * c * c), 1e-30)


def ggx_alpha(roughness):
    """GGX width a = R^2, floored at MIN_GGX_ALPHA."""
    return dr.maximum(roughness * roughness, MIN_GGX_ALPHA)


def _check_masking(masking: str) -> None:
    if masking not in MASKING_MODELS:
        raise SatsightError(
            f"unknown GGX masking '{masking}'; use one of {', '.join(MASKING_MODELS)}"
        )


def _masking_product(cos_i, cos_o, roughness, alpha, masking: str):
    _check_masking(masking)
    if masking == "smith":
        return smith_ggx_g1(cos_i, alpha) * smith_ggx_g1(cos_o, alpha)
    return schlick_ggx_g1(cos_i, roughness) * schlick_ggx_g1(cos_o, roughness)


def ggx_distribution_h(h, alpha):
    """GGX D(h) (sr^-1) from the unit half vector h itself, for narrow lobes.

    Same function as ``ggx_distribution`` written as a^2 / (pi (a^2 h_z^2 + h_x^2 + h_y^2)^2):
    the sine part h_x^2 + h_y^2 is exact where ``1 - cos^2`` in float32 is not (at a = 1e-3
    the cosine form is off by several per cent near the peak).
    """
    a2 = alpha * alpha
    t = a2 * h.z * h.z + (h.x * h.x + h.y * h.y)
    return a2 * INV_PI / dr.maximum(t * t, 1e-30)


def _ggx_parts(cos_i, cos_o, d, cos_d, base_rgb, metallic, roughness, ior, masking):
    """(diffuse, specular) parts of the model for the distribution value d = D(h), without
    the horizon test."""
    alpha = ggx_alpha(roughness)
    f_d = fresnel_dielectric(cos_d, ior)
    f = metallic * fresnel_schlick(base_rgb, cos_d) + (1.0 - metallic) * f_d
    g = _masking_product(cos_i, cos_o, roughness, alpha, masking)
    specular = f * (d * g / dr.maximum(4.0 * cos_i * cos_o, 1e-12))
    transmitted = (1.0 - fresnel_dielectric(cos_i, ior)) * (1.0 - fresnel_dielectric(cos_o, ior))
    diffuse = (1.0 - metallic) * transmitted * INV_PI * base_rgb
    return diffuse, specular


def ggx_metallic_brdf(
    cos_i, cos_o, cos_h, cos_d, base_rgb, metallic, roughness, ior, masking: str = "schlick"
):
    """BRDF value (per channel, sr^-1) of the metallic/roughness/IOR model.

    cos_i = n.wi (to the light), cos_o = n.wo (to the viewer), cos_h = n.h,
    cos_d = wi.h with h the half vector. base_rgb: linear base colour (Color3f).
    metallic, roughness in [0, 1]; ior >= 1. Zero where either cosine is <= 0.
    masking: "schlick" (paper, default) or "smith" (exact separable Smith G1).
    """
    d = ggx_distribution(cos_h, ggx_alpha(roughness))
    diffuse, specular = _ggx_parts(
        cos_i, cos_o, d, cos_d, base_rgb, metallic, roughness, ior, masking
    )
    valid = (cos_i > 0.0) & (cos_o > 0.0)
    return dr.select(valid, diffuse + specular, 0.0)


# ----------------------------------------------------------------------------------------
# Vector interface


def validate_ggx_parameters(base_rgb, metallic, roughness, ior) -> None:
    """Raise ``SatsightError`` unless base colour, M, R are in [0, 1] and IOR is finite >= 1.

    base_rgb: 3 values or an (n, 3) array; the others numbers or (n,) arrays.
    """
    problems = []
    base = np.asarray(base_rgb, dtype=np.float64)
    if base.ndim == 0 or base.ndim > 2 or base.shape[-1] != 3:
        problems.append(f"base colour must be 3 values or an (n, 3) array, got {base.shape}")
    elif not np.all((base >= 0.0) & (base <= 1.0)):
        problems.append(f"base colour must be in [0, 1], got {base.min():g}..{base.max():g}")
    for name, value in (("metallic", metallic), ("roughness", roughness)):
        v = np.asarray(value, dtype=np.float64)
        if not np.all((v >= 0.0) & (v <= 1.0)):
            problems.append(f"{name} must be in [0, 1], got {v.min():g}..{v.max():g}")
    n = np.asarray(ior, dtype=np.float64)
    if not np.all(np.isfinite(n) & (n >= 1.0)):
        problems.append(f"ior must be a finite number >= 1, got {n.min():g}..{n.max():g}")
    if problems:
        raise SatsightError("GGX parameters: " + "; ".join(problems))


@dataclass(frozen=True)
class GGXParams:
    """Metallic/roughness/IOR parameters, one value per lane (width 1 broadcasts).

    base: ``mi.Color3f`` linear base colour; metallic, roughness, ior: ``mi.Float``;
    masking: "schlick" (paper, default) or "smith", the same for all lanes.
    """

    base: mi.Color3f
    metallic: mi.Float
    roughness: mi.Float
    ior: mi.Float
    masking: str = "schlick"

    def __post_init__(self) -> None:
        _check_masking(self.masking)

    @classmethod
    def from_values(cls, base_rgb, metallic, roughness, ior, masking="schlick") -> GGXParams:
        """Validated parameters from numbers: base 3 values or (n, 3), others scalar or (n,)."""
        validate_ggx_parameters(base_rgb, metallic, roughness, ior)
        base = np.atleast_2d(np.asarray(base_rgb, dtype=np.float64))
        m, r, n = (
            np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (metallic, roughness, ior)
        )
        try:
            lanes = np.broadcast_shapes(base.shape[:1], m.shape, r.shape, n.shape)
        except ValueError:
            raise SatsightError(
                "GGX parameters: per-lane arrays must have a common length, got "
                f"{base.shape[0]}, {m.size}, {r.size}, {n.size}"
            ) from None

        def as_float(v):
            return mi.Float(np.ascontiguousarray(np.broadcast_to(v, lanes), dtype=np.float32))

        base = np.broadcast_to(base, (*lanes, 3))
        return cls(
            mi.Color3f(np.ascontiguousarray(base.T, dtype=np.float32)),
            as_float(m),
            as_float(r),
            as_float(n),
            masking,
        )

    @classmethod
    def from_material(cls, material, masking: str = "schlick") -> GGXParams:
        """Parameters of a ``satsight.scene.materials.Material`` (one lane)."""
        return cls.from_values(
            material.base_color_rgb, material.metallic, material.roughness, material.ior, masking
        )


def _vector_terms(wi, wo, params: GGXParams):
    """(cos_i, cos_o, D(h), cos_d) with h = normalize(wi + wo)."""
    h = dr.normalize(wi + wo)
    return wi.z, wo.z, ggx_distribution_h(h, ggx_alpha(params.roughness)), dr.dot(wi, h)


def ggx_eval(wi, wo, params: GGXParams):
    """BRDF value f_r (Color3f, sr^-1) of the model for unit wi (light) and wo (viewer).

    The function of ``ggx_metallic_brdf`` with the cosines of wi, wo and
    h = normalize(wi + wo); D(h) is evaluated from h (``ggx_distribution_h``), which keeps
    float32 precision for the narrowest lobes (a down to MIN_GGX_ALPHA).
    Zero where wi.z <= 0 or wo.z <= 0.
    """
    diffuse, specular = ggx_eval_parts(wi, wo, params)
    return diffuse + specular


def ggx_eval_parts(wi, wo, params: GGXParams):
    """(diffuse, specular) parts of ``ggx_eval`` (Color3f, sr^-1), computed once; their sum
    is ``ggx_eval``."""
    cos_i, cos_o, d, cos_d = _vector_terms(wi, wo, params)
    diffuse, specular = _ggx_parts(
        cos_i,
        cos_o,
        d,
        cos_d,
        params.base,
        params.metallic,
        params.roughness,
        params.ior,
        params.masking,
    )
    valid = (cos_i > 0.0) & (cos_o > 0.0)
    return dr.select(valid, diffuse, 0.0), dr.select(valid, specular, 0.0)


def ggx_eval_specular(wi, wo, params: GGXParams):
    """Specular part F D G / (4 cos_i cos_o) of ``ggx_eval`` (Color3f, sr^-1)."""
    return ggx_eval_parts(wi, wo, params)[1]


def _f0_dielectric(ior):
    r = (ior - 1.0) / (ior + 1.0)
    return r * r


def _mean(color):
    return (color.x + color.y + color.z) * (1.0 / 3.0)


def ggx_diffuse_probability(params: GGXParams):
    """Probability with which ``ggx_sample`` draws the cosine-weighted diffuse lobe.

    p_d = w_d / (w_d + w_s) with w_d = mean((1 - M) base (1 - F0)) and
    w_s = mean(M base + (1 - M) F0) (= mean(ks)), clamped to [0.05, 0.95]; p_d = 0 when the
    diffuse part is zero (M = 1 or black base) and 1 when the specular part is zero
    (M = 0 and IOR = 1).
    """
    f0 = _f0_dielectric(params.ior)
    w_d = _mean((1.0 - params.metallic) * (1.0 - f0) * params.base)
    w_s = _mean(params.metallic * params.base) + (1.0 - params.metallic) * f0
    p = w_d / dr.maximum(w_d + w_s, 1e-30)
    p = dr.clip(p, MIN_LOBE_PROBABILITY, 1.0 - MIN_LOBE_PROBABILITY)
    p = dr.select(w_d <= 0.0, 0.0, p)
    return dr.select((params.metallic <= 0.0) & (params.ior <= 1.0), 1.0, p)


def sample_ggx_half_vector(u, alpha):
    """Microfacet normal h with density D(h) cos(theta_h) (sr^-1) for GGX of width alpha.

    Inverting the CDF of the GGX slope distribution: tan^2(theta_h) = alpha^2 u / (1 - u),
    phi = 2 pi u' (Walter et al. 2007, Eq. 35-36); cos^2 and sin^2 are formed separately
    so that narrow lobes keep their precision.
    """
    a2 = alpha * alpha
    denom = dr.maximum((1.0 - u.x) + a2 * u.x, 1e-30)
    cos2 = dr.maximum(1.0 - u.x, 0.0) / denom
    sin2 = a2 * u.x / denom
    sin_phi, cos_phi = dr.sincos(TWO_PI * u.y)
    sin_t = dr.sqrt(dr.maximum(sin2, 0.0))
    return mi.Vector3f(sin_t * cos_phi, sin_t * sin_phi, dr.sqrt(cos2))


def _specular_pdf(wi, wo, alpha):
    h = dr.normalize(wi + wo)
    cos_oh = dr.dot(wo, h)
    return ggx_distribution_h(h, alpha) * dr.maximum(h.z, 0.0) / dr.maximum(4.0 * cos_oh, 1e-12)


def _mixture_pdf(wi, wo, params: GGXParams, p_diffuse):
    alpha = ggx_alpha(params.roughness)
    pdf = p_diffuse * cosine_hemisphere_pdf(wi) + (1.0 - p_diffuse) * _specular_pdf(wi, wo, alpha)
    return dr.select((wi.z > 0.0) & (wo.z > 0.0), pdf, 0.0)


def ggx_pdf(wi, wo, params: GGXParams):
    """Density (sr^-1) with which ``ggx_sample`` returns wi:
    p_d cos(theta_i) / pi + (1 - p_d) D(h) cos(theta_h) / (4 wo.h); 0 below the horizon."""
    return _mixture_pdf(wi, wo, params, ggx_diffuse_probability(params))


def ggx_sample(wo, u_lobe, u2, params: GGXParams):
    """Light direction wi for the viewer direction wo, and its density (sr^-1).

    u_lobe < p_d (``ggx_diffuse_probability``) draws the diffuse lobe cosine-weighted from
    u2, otherwise u2 draws a GGX microfacet normal h and wi = reflect(wo, h). The density
    is the mixture's (``ggx_pdf``) and 0 when wi falls below the horizon.
    """
    p_diffuse = ggx_diffuse_probability(params)
    wi_diffuse = square_to_cosine_hemisphere(u2)
    h = sample_ggx_half_vector(u2, ggx_alpha(params.roughness))
    wi_specular = reflect(wo, h)
    wi = dr.select(u_lobe < p_diffuse, wi_diffuse, wi_specular)
    return wi, _mixture_pdf(wi, wo, params, p_diffuse)


def ggx_diffuse_coefficient(params: GGXParams, wo):
    """(kd_eq, exponent) for the diffuse part seen from the viewer direction wo.

    The diffuse part is kd_eq / pi * (1 - F_d(cos theta_i)) with
    kd_eq = (1 - M) base (1 - F_d(wo.z)) and exponent 0: a zonal function of theta_i times
    a per-lane constant, so its product with an SH environment is exact through the
    Funk-Hecke factors of the kernel ``ggx_diffuse_kernel`` (no approximation).
    """
    kd = (1.0 - params.metallic) * (1.0 - fresnel_dielectric(wo.z, params.ior)) * params.base
    return kd, dr.zeros(mi.Float, dr.width(params.metallic))


def fresnel_dielectric_np(cos_theta: np.ndarray, ior: float) -> np.ndarray:
    """``fresnel_dielectric`` in float64 numpy (same closed form)."""
    c = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    if ior <= 1.0:
        return np.zeros_like(c)
    g = np.sqrt(ior * ior - 1.0 + c * c)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


def ggx_diffuse_kernel(ior: float):
    """The zonal kernel k(t) = (1 - F_d(t)) max(t, 0) of the diffuse part (t = cos theta_i),
    as a numpy function, for SH convolution (``satsight.lighting.sh.zonal_kernel_coeffs``)."""
    return lambda t: (1.0 - fresnel_dielectric_np(t, ior)) * np.maximum(t, 0.0)
