"""The metallic / roughness / IOR GGX reflection model of the paper (Eq. 18-20), in Dr.Jit.

All functions take Dr.Jit arrays (any backend) of cosines between unit vectors in the
shading frame and return the BRDF value f_r in sr^-1, so that reflected radiance is
``L_r = f_r * E * cos(theta_i)`` for a collimated source of irradiance E (W m^-2).

Model (reading of Eq. 18-20 recorded in docs/design.md)::

    f_r = (1 - M) * base * (1 - F_d(h.wi)) / pi                       diffuse
        + F(h.wi) * D(n.h) * G(n.wi) G(n.wo) / (4 (n.wi) (n.wo))       specular

    F   = M * Schlick(base, h.wi) + (1 - M) * F_d(h.wi)   -> ks = M base + (1 - M) F0 at 0 deg
    F_d = exact unpolarised Fresnel reflectance of a dielectric of index IOR (F_d = 0 at IOR 1)
    D   = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2),  a = R^2         (GGX / Trowbridge-Reitz)
    G   = x / (x (1 - k) + k),  k = (R + 1)^2 / 8                (Schlick-GGX, Smith form)
"""

from __future__ import annotations

import math

import drjit as dr

INV_PI = 1.0 / math.pi
# Lower bound of the GGX width a = R^2 so that a perfectly smooth setting stays finite
# in float32 (peak D = 1 / (pi a^2)).
MIN_GGX_ALPHA = 1e-3


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


def ggx_metallic_brdf(cos_i, cos_o, cos_h, cos_d, base_rgb, metallic, roughness, ior):
    """BRDF value (per channel, sr^-1) of the metallic/roughness/IOR model.

    cos_i = n.wi (to the light), cos_o = n.wo (to the viewer), cos_h = n.h,
    cos_d = wi.h with h the half vector. base_rgb: linear base colour (Color3f).
    metallic, roughness in [0, 1]; ior >= 1. Zero where either cosine is <= 0.
    """
    alpha = dr.maximum(roughness * roughness, MIN_GGX_ALPHA)
    f_d = fresnel_dielectric(cos_d, ior)
    f = metallic * fresnel_schlick(base_rgb, cos_d) + (1.0 - metallic) * f_d
    d = ggx_distribution(cos_h, alpha)
    g = schlick_ggx_g1(cos_i, roughness) * schlick_ggx_g1(cos_o, roughness)
    valid = (cos_i > 0.0) & (cos_o > 0.0)
    specular = f * (d * g / dr.maximum(4.0 * cos_i * cos_o, 1e-12))
    diffuse = (1.0 - metallic) * (1.0 - f_d) * INV_PI * base_rgb
    return dr.select(valid, diffuse + specular, 0.0)
