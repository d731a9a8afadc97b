"""The renderer's three reflection models as float64 numpy functions, for fitting to data.

Each function returns the BRDF value f_r (sr^-1) of the model that ``satsight.render``
evaluates in Dr.Jit, written out again from its definition (docs/design.md, "Reflection
models: the reading of Eq. 16-17" and "GGX metallic/roughness model: the reading of
Eq. 18-20"):

* ``phong_brdf``: original Phong (paper Eq. 16), energy-normalised
  (Lafortune & Willems 1994): ``kd / pi + ks (g + 2) / (2 pi) cos^g(beta)``.
* ``improved_phong_brdf``: the improved model (paper Eq. 17)
  ``kd / pi cos^c(theta_i) + ks N(g, a, b) cos^g(beta) exp(-b (1 - cos beta)^(1/pi))
  / max(cos theta_i, MU_MIN)^a``, with the renderer's normalisation N (computed by
  ``satsight.render.phong.improved_phong_lobe_scale`` in float64, so that fitted and
  rendered materials are one and the same function).
* ``ggx_brdf``: the metallic / roughness / IOR model (paper Eq. 18-20) in the Cook-Torrance
  form, exact dielectric Fresnel for the dielectric part and Schlick's for the metal,
  diffuse weight (1 - F_d(n.wi)) (1 - F_d(n.wo)), GGX D with alpha = max(R^2, 1e-3) and
  Schlick-GGX (or exact Smith) masking.

Conventions (those of ``satsight.render.sampling``): directions are unit vectors in the
local frame of the surface, whose normal is +z; ``wi`` points towards the light, ``wo``
towards the viewer, both away from the surface; beta is the angle between wi and the
mirror direction of wo, (-wo_x, -wo_y, wo_z). BRDFs are 0 where wi or wo is at or below the
horizon.

Shapes: ``wi`` and ``wo`` are (..., 3) arrays, components on the last axis. Every parameter
broadcasts against their leading shape (...): a number, one value per direction pair, or,
with directions of shape (N, 1, 3) and parameters of shape (C,), one value per colour
channel (result (N, C)).

``directional_albedo`` integrates any of them over the viewer hemisphere (energy check).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from satsight.render.phong import MU_MIN, improved_phong_lobe_scale

MIN_GGX_ALPHA = 1e-3
"""Floor of the GGX width alpha = R^2 (the renderer's, ``satsight.render.ggx``)."""

MASKINGS = ("schlick", "smith")


def unit_vectors_from_angles(theta_rad, phi_rad) -> np.ndarray:
    """Unit vectors (..., 3) at polar angle theta from +z and azimuth phi from +x (radians)."""
    theta, phi = np.broadcast_arrays(
        np.asarray(theta_rad, dtype=np.float64), np.asarray(phi_rad, dtype=np.float64)
    )
    sin_t = np.sin(theta)
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), np.cos(theta)], axis=-1)


def mirror_about_normal(v: np.ndarray) -> np.ndarray:
    """Mirror direction of v about the normal +z: (-x, -y, z)."""
    return v * np.array([-1.0, -1.0, 1.0])


def _valid(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    return (wi[..., 2] > 0.0) & (wo[..., 2] > 0.0)


def _cos_beta(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """cos(beta), beta between wi and the mirror direction of wo, clamped at 0."""
    return np.maximum(np.sum(wi * mirror_about_normal(wo), axis=-1), 0.0)


def phong_brdf(wi, wo, kd, ks, g) -> np.ndarray:
    """Original Phong BRDF kd / pi + ks (g + 2) / (2 pi) cos^g(beta), sr^-1.

    kd, ks: diffuse and specular reflectances (kd + ks <= 1 conserves energy); g >= 1: the
    gloss exponent. Same function as ``satsight.render.phong.phong_eval``.
    """
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    kd, ks, g = (np.asarray(v, dtype=np.float64) for v in (kd, ks, g))
    lobe = (g + 2.0) / (2.0 * math.pi) * _cos_beta(wi, wo) ** g
    value = kd / math.pi + ks * lobe
    return np.where(_valid(wi, wo), value, 0.0)


def improved_phong_lobe_scale_np(g, a, b) -> np.ndarray:
    """N(g, a, b) 2 pi / (g + 2) for scalar or array g, a, b (the renderer's normalisation,
    one float64 quadrature per distinct triple)."""
    g, a, b = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (g, a, b)))
    if g.ndim == 0:
        return np.asarray(improved_phong_lobe_scale(float(g), float(a), float(b)))
    keys = np.stack([g.ravel(), a.ravel(), b.ravel()], axis=1)
    unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    scales = np.array([improved_phong_lobe_scale(*map(float, row)) for row in unique])
    return scales[inverse.reshape(-1)].reshape(g.shape)


def improved_phong_brdf(wi, wo, kd, ks, g, a, b, c, lobe_scale=None) -> np.ndarray:
    """Improved Phong BRDF (paper Eq. 17 as read in docs/design.md), sr^-1::

        kd / pi cos^c(theta_i)
        + ks (g + 2) / (2 pi) s(g, a, b) cos^g(beta) exp(-b (1 - cos beta)^(1/pi))
          / max(cos theta_i, MU_MIN)^a

    kd, ks reflectances (kd + ks <= 1), g >= 1 gloss exponent, a in [0, 1] grazing
    exponent, b >= 0 lobe decay, c >= 0 diffuse exponent. lobe_scale s = N 2 pi / (g + 2)
    is computed from (g, a, b) when not given (``improved_phong_lobe_scale_np``). Same
    function as ``satsight.render.phong.improved_phong_eval``; a = b = c = 0 is Phong.
    """
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    kd, ks, g, a, b, c = (np.asarray(v, dtype=np.float64) for v in (kd, ks, g, a, b, c))
    if lobe_scale is None:
        lobe_scale = improved_phong_lobe_scale_np(g, a, b)
    cos_i = np.maximum(wi[..., 2], 0.0)
    cos_beta = _cos_beta(wi, wo)
    one_minus_cos = np.maximum(1.0 - cos_beta, 0.0)
    shape = cos_beta**g * np.exp(-b * one_minus_cos ** (1.0 / math.pi))
    grazing = np.maximum(cos_i, MU_MIN) ** a
    lobe = (g + 2.0) / (2.0 * math.pi) * lobe_scale * shape / grazing
    value = kd / math.pi * cos_i**c + ks * lobe
    return np.where(_valid(wi, wo), value, 0.0)


def fresnel_dielectric_unpolarised(cos_theta, ior) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a dielectric of real index ior >= 1 seen from
    vacuum, at incidence cosine cos_theta (Born & Wolf); 0 for ior = 1.

    With n the index, cos_t the cosine of the refracted ray:
    R = (|r_s|^2 + |r_p|^2) / 2, r_s = (c - n cos_t) / (c + n cos_t),
    r_p = (n c - cos_t) / (n c + cos_t).
    """
    c = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    n = np.asarray(ior, dtype=np.float64)
    n_safe = np.maximum(n, 1.0)
    sin_t2 = (1.0 - c * c) / (n_safe * n_safe)
    cos_t = np.sqrt(np.maximum(1.0 - sin_t2, 0.0))
    rs = (c - n_safe * cos_t) / np.maximum(c + n_safe * cos_t, 1e-300)
    rp = (n_safe * c - cos_t) / np.maximum(n_safe * c + cos_t, 1e-300)
    r = 0.5 * (rs * rs + rp * rp)
    return np.where(n > 1.0, r, 0.0)


def _schlick(f0, cos_theta):
    m = 1.0 - np.clip(cos_theta, 0.0, 1.0)
    return f0 + (1.0 - f0) * m**5


def _ggx_d_from_half_vector(h: np.ndarray, alpha) -> np.ndarray:
    """GGX D(h) = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2), written with the sine part
    h_x^2 + h_y^2 so that narrow lobes keep their precision."""
    a2 = alpha * alpha
    t = a2 * h[..., 2] ** 2 + h[..., 0] ** 2 + h[..., 1] ** 2
    return a2 / (math.pi * np.maximum(t * t, 1e-300))


def _g1_schlick_ggx(cos_theta, roughness):
    k = (roughness + 1.0) ** 2 / 8.0
    c = np.maximum(cos_theta, 0.0)
    return c / (c * (1.0 - k) + k)


def _g1_smith_ggx(cos_theta, alpha):
    c = np.maximum(cos_theta, 0.0)
    a2 = alpha * alpha
    return 2.0 * c / np.maximum(c + np.sqrt(a2 + (1.0 - a2) * c * c), 1e-300)


def ggx_brdf(wi, wo, base, metallic, roughness, ior, masking: str = "schlick") -> np.ndarray:
    """Metallic / roughness / IOR GGX BRDF (paper Eq. 18-20, docs/design.md), sr^-1::

        (1 - M) base (1 - F_d(n.wi)) (1 - F_d(n.wo)) / pi
        + F(wi.h) D(h) G1(n.wi) G1(n.wo) / (4 n.wi n.wo),
        F = M Schlick(base, wi.h) + (1 - M) F_d(wi.h)

    base in [0, 1] (per channel), metallic M and roughness R in [0, 1], ior >= 1; alpha =
    max(R^2, MIN_GGX_ALPHA); masking "schlick" (k = (R + 1)^2 / 8, the paper's) or "smith"
    (exact separable Smith G1 of GGX). Same function as ``satsight.render.ggx.ggx_eval``.
    """
    if masking not in MASKINGS:
        raise ValueError(f"masking must be one of {MASKINGS}, got {masking!r}")
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    base, m, r, n = (np.asarray(v, dtype=np.float64) for v in (base, metallic, roughness, ior))
    alpha = np.maximum(r * r, MIN_GGX_ALPHA)
    half = wi + wo
    half = half / np.maximum(np.linalg.norm(half, axis=-1, keepdims=True), 1e-300)
    cos_i, cos_o = wi[..., 2], wo[..., 2]
    cos_d = np.sum(wi * half, axis=-1)
    fresnel = m * _schlick(base, cos_d) + (1.0 - m) * fresnel_dielectric_unpolarised(cos_d, n)
    if masking == "smith":
        shadowing = _g1_smith_ggx(cos_i, alpha) * _g1_smith_ggx(cos_o, alpha)
    else:
        shadowing = _g1_schlick_ggx(cos_i, r) * _g1_schlick_ggx(cos_o, r)
    specular = (
        fresnel
        * _ggx_d_from_half_vector(half, alpha)
        * shadowing
        / np.maximum(4.0 * cos_i * cos_o, 1e-12)
    )
    transmitted = (1.0 - fresnel_dielectric_unpolarised(cos_i, n)) * (
        1.0 - fresnel_dielectric_unpolarised(cos_o, n)
    )
    diffuse = (1.0 - m) * base * transmitted / math.pi
    return np.where(_valid(wi, wo), diffuse + specular, 0.0)


# ----------------------------------------------------------------------------------------
# Energy: directional albedo by quadrature

_NODES_PER_SEGMENT = 16


def graded_beta_nodes(
    lobe_width_rad: float, nodes_per_segment: int
) -> tuple[np.ndarray, np.ndarray]:
    """Nodes beta in [0, pi] (rad) from a lobe's axis and their weights sin(beta) d beta:
    Gauss-Legendre with ``nodes_per_segment`` points on segments graded geometrically from
    lobe_width_rad / 8 (clipped to [1e-6, 1] rad) out to pi, so a narrow lobe and the wide
    rest are both resolved."""
    x, w = np.polynomial.legendre.leggauss(nodes_per_segment)
    width = float(np.clip(lobe_width_rad, 1e-6, 1.0))
    edges = [0.0]
    edge = width / 8.0
    while edge < math.pi:
        edges.append(edge)
        edge *= 2.0
    edges.append(math.pi)
    lo, hi = np.array(edges[:-1])[:, None], np.array(edges[1:])[:, None]
    beta = (0.5 * (hi - lo) * x + 0.5 * (hi + lo)).ravel()
    return beta, (0.5 * (hi - lo) * w).ravel() * np.sin(beta)


def directional_albedo(
    brdf: Callable[[np.ndarray, np.ndarray], np.ndarray],
    theta_i_rad: float,
    lobe_width_rad: float = 0.5,
    n_phi: int = 256,
) -> np.ndarray:
    """Directional albedo A(theta_i) = integral of f_r(wi, wo) cos(theta_o) d omega_o over
    the viewer hemisphere (dimensionless; <= 1 conserves energy), float64 quadrature.

    brdf(wi, wo) takes (..., 3) direction arrays and returns (...) or (..., C) values; the
    result has shape () or (C,). The integral runs in spherical coordinates (beta, psi)
    around the mirror direction of wi, where the specular lobes peak: beta by Gauss-Legendre
    on segments graded geometrically from lobe_width_rad / 8 out to pi, psi by the
    midpoint rule with n_phi nodes. The horizon cut makes the integrand's derivative jump,
    which limits the accuracy to about 1e-4 for n_phi = 256.
    """
    beta, w_beta = graded_beta_nodes(lobe_width_rad, _NODES_PER_SEGMENT)
    psi = (np.arange(n_phi) + 0.5) * (2.0 * math.pi / n_phi)
    w_psi = 2.0 * math.pi / n_phi

    wi = unit_vectors_from_angles(theta_i_rad, 0.0)
    axis = mirror_about_normal(wi)  # mirror direction of wi
    # Orthonormal frame around the axis: e1 in the plane of incidence, e2 = y.
    e2 = np.array([0.0, 1.0, 0.0])
    e1 = np.cross(e2, axis)
    local = unit_vectors_from_angles(beta[:, None], psi[None, :])  # (n_beta, n_phi, 3)
    wo = local[..., 0:1] * e1 + local[..., 1:2] * e2 + local[..., 2:3] * axis
    cos_o = np.maximum(wo[..., 2], 0.0)
    values = np.asarray(brdf(np.broadcast_to(wi, wo.shape), wo), dtype=np.float64)
    weight = w_beta[:, None] * w_psi * cos_o
    if values.ndim == weight.ndim + 1:
        return np.einsum("ij,ijc->c", weight, values)
    return np.asarray(np.sum(weight * values))


def phong_lobe_width_rad(g: float) -> float:
    """Angular width of a cos^g lobe, sqrt(2 / (g + 2)) (where it falls to about 1/e)."""
    return math.sqrt(2.0 / (float(g) + 2.0))


def ggx_lobe_width_rad(roughness: float) -> float:
    """Angular width of the GGX reflection lobe around the mirror direction, ~2 alpha."""
    return 2.0 * max(float(roughness) ** 2, MIN_GGX_ALPHA)
