"""Phong reflection models of the paper (Eq. 16 and 17), physically normalised, in Dr.Jit.

Frame and direction conventions are those of ``satsight.render.sampling``: local shading
frame with the normal +z, ``wi`` towards the light, ``wo`` towards the viewer. BRDF values
are in sr^-1, so a collimated source of irradiance E gives ``L = f_r E cos(theta_i)``.

Original Phong (paper Eq. 16) in the energy-normalised form of Lafortune & Willems 1994,
"Using the modified Phong reflectance model for physically based rendering"::

    f_r = kd / pi + ks (g + 2) / (2 pi) cos^g(beta)

with beta the angle between wi and the mirror direction of wo about the normal (cos beta
clamped at 0), kd and ks per colour channel and the gloss exponent g >= 1. The lobe's
directional albedo is at most ks (equal at normal incidence), so kd + ks <= 1 conserves
energy.

Improved Phong (paper Eq. 17; the extracted text lost fraction bars and signs, this is the
physically sound reading)::

    f_r = kd / pi cos^c(theta_i)
        + ks N(g, a, b) cos^g(beta) exp(-b (1 - cos beta)^(1/pi)) / max(cos theta_i, MU_MIN)^a

c >= 0 modifies the diffuse part (c = 0: Lambert, the paper's form is c = 1), a in [0, 1] is
the grazing-incidence (Fresnel-like) exponent, b >= 0 narrows the lobe (the minus sign keeps
the factor <= 1), and MU_MIN = 0.02 keeps the grazing factor finite. The normalisation is
N = (g + 2) / (2 pi) / A_max with A_max the largest directional albedo, over incidence
angles, of the lobe written with (g + 2) / (2 pi) (see ``improved_phong_normalization``).
With a = 0 the exp factor is <= 1 and Phong's bound holds, so A_max = 1 exactly and
a = b = c = 0 is exactly the original Phong model. The improved model is not reciprocal
(it depends on theta_i alone): its energy bound is the one for a fixed incident direction,
integral of f_r cos(theta_o) over the viewer hemisphere <= kd + ks.

Parameter containers: ``PhongParams`` and ``ImprovedPhongParams`` hold Dr.Jit arrays with
one value per lane (width 1 broadcasts), so every pixel may carry its own material. Build
them with ``from_values``, which validates numbers given in numpy (``SatsightError`` on
values out of range) and computes the improved model's normalisation per distinct (g, a, b)
in float64.

Sampling (both models): a mixture that picks the diffuse part with probability
p_d = mean(kd) / (mean(kd) + mean(ks)) and samples it cosine-weighted, and otherwise the
Phong lobe cos^g(beta) around the mirror direction of wo. ``*_sample`` returns the light
direction wi and its mixture density in solid angle; the density is 0 where wi falls below
the horizon (such samples carry no light).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import drjit as dr
import mitsuba as mi
import numpy as np
from scipy.optimize import minimize_scalar

from satsight.errors import SatsightError
from satsight.render.sampling import (
    INV_PI,
    INV_TWO_PI,
    cosine_hemisphere_pdf,
    mirror_local,
    phong_lobe_pdf,
    safe_power,
    sample_phong_lobe,
    square_to_cosine_hemisphere,
)

MU_MIN = 0.02
"""Floor of cos(theta_i) in the improved model's grazing factor 1 / max(cos theta_i, MU_MIN)^a."""

ALBEDO_MARGIN = 1e-3
"""Relative margin added to the quadrature maximum A_max when a > 0."""

MIN_GLOSS_EXPONENT = 1.0
MAX_GLOSS_EXPONENT = 1e5
"""float32 resolves 1 - cos(beta) down to ~6e-8: narrower lobes (g > 1e5) lose their shape."""

_LOBE_CUTOFF = 1e-12  # cos^g(beta) below this is left out of the albedo quadrature
_NODES_PER_SEGMENT = 24


# ----------------------------------------------------------------------------------------
# Parameters: validation in numpy, containers of Dr.Jit arrays


def _as_lanes(rgb_values: dict[str, object], scalar_values: dict[str, object]):
    """Broadcast colours to (n, 3) and scalars to (n,) float64 arrays with one common n."""
    rgb = {k: np.asarray(v, dtype=np.float64) for k, v in rgb_values.items()}
    scalars = {k: np.asarray(v, dtype=np.float64) for k, v in scalar_values.items()}
    for key, value in rgb.items():
        if value.ndim == 0:
            rgb[key] = value = np.full(3, float(value))  # grey
        if value.shape[-1] != 3 or value.ndim > 2:
            raise SatsightError(
                f"{key} must be a number, 3 values (R, G, B) or an (n, 3) array, "
                f"got shape {value.shape}"
            )
    for key, value in scalars.items():
        if value.ndim > 1:
            raise SatsightError(f"{key} must be a number or a 1-D array, got shape {value.shape}")
    shapes = [v.shape[:-1] for v in rgb.values()] + [v.shape for v in scalars.values()]
    try:
        (n,) = np.broadcast_shapes(*shapes, (1,))
    except ValueError:
        raise SatsightError(
            "per-lane parameters must have a common length; got shapes "
            + ", ".join(f"{k}: {v.shape}" for k, v in (rgb | scalars).items())
        ) from None
    rgb = {k: np.broadcast_to(v, (n, 3)) for k, v in rgb.items()}
    scalars = {k: np.broadcast_to(v, (n,)) for k, v in scalars.items()}
    return rgb, scalars


def _check(problems: list[str], name: str, values: np.ndarray, ok: np.ndarray, rule: str) -> None:
    bad = ~ok
    if np.any(bad):
        first = values[bad].reshape(-1)[0]
        count = int(np.count_nonzero(bad))
        where = f" ({count} values out of range)" if count > 1 else ""
        problems.append(f"{name} must be {rule}, got {first:g}{where}")


def _check_common(problems, kd, ks, g) -> None:
    _check(problems, "kd", kd, np.isfinite(kd) & (kd >= 0.0) & (kd <= 1.0), "in [0, 1]")
    _check(problems, "ks", ks, np.isfinite(ks) & (ks >= 0.0) & (ks <= 1.0), "in [0, 1]")
    total = kd + ks
    _check(
        problems,
        "kd + ks",
        total,
        ~(total > 1.0 + 1e-9),
        "<= 1 in every channel (energy conservation)",
    )
    _check(
        problems,
        "gloss exponent g",
        g,
        np.isfinite(g) & (g >= MIN_GLOSS_EXPONENT) & (g <= MAX_GLOSS_EXPONENT),
        f"a number in [{MIN_GLOSS_EXPONENT:g}, {MAX_GLOSS_EXPONENT:g}]",
    )


def _raise(model: str, problems: list[str]) -> None:
    if problems:
        raise SatsightError(f"{model} parameters: " + "; ".join(problems))


def validate_phong_parameters(kd, ks, g) -> None:
    """Raise ``SatsightError`` unless kd, ks in [0, 1] per channel, kd + ks <= 1, 1 <= g <= 1e5.

    kd, ks: a number (grey), 3 values or (n, 3) arrays; g: a number or an (n,) array.
    """
    rgb, s = _as_lanes({"kd": kd, "ks": ks}, {"g": g})
    problems: list[str] = []
    _check_common(problems, rgb["kd"], rgb["ks"], s["g"])
    _raise("Phong", problems)


def validate_improved_phong_parameters(kd, ks, g, a, b, c) -> None:
    """As ``validate_phong_parameters``, and a in [0, 1], b >= 0 and c >= 0 (finite)."""
    rgb, s = _as_lanes({"kd": kd, "ks": ks}, {"g": g, "a": a, "b": b, "c": c})
    problems: list[str] = []
    _check_common(problems, rgb["kd"], rgb["ks"], s["g"])
    a_, b_, c_ = s["a"], s["b"], s["c"]
    _check(problems, "a", a_, np.isfinite(a_) & (a_ >= 0.0) & (a_ <= 1.0), "in [0, 1]")
    _check(problems, "b", b_, np.isfinite(b_) & (b_ >= 0.0), "a finite number >= 0")
    _check(problems, "c", c_, np.isfinite(c_) & (c_ >= 0.0), "a finite number >= 0")
    _raise("improved Phong", problems)


def _float(values: np.ndarray):
    return mi.Float(np.ascontiguousarray(values, dtype=np.float32))


def _color(values: np.ndarray):
    return mi.Color3f(np.ascontiguousarray(np.asarray(values).T, dtype=np.float32))


@dataclass(frozen=True)
class PhongParams:
    """Original Phong parameters, one value per lane.

    kd, ks: ``mi.Color3f`` diffuse and specular reflectances; g: ``mi.Float`` gloss exponent.
    """

    kd: mi.Color3f
    ks: mi.Color3f
    g: mi.Float

    @classmethod
    def from_values(cls, kd, ks, g) -> PhongParams:
        """Validated parameters from numbers: kd, ks grey, 3 values or (n, 3); g scalar or (n,)."""
        validate_phong_parameters(kd, ks, g)
        rgb, s = _as_lanes({"kd": kd, "ks": ks}, {"g": g})
        return cls(_color(rgb["kd"]), _color(rgb["ks"]), _float(s["g"]))


@dataclass(frozen=True)
class ImprovedPhongParams:
    """Improved Phong parameters, one value per lane.

    kd, ks: ``mi.Color3f``; g, a, b, c: ``mi.Float`` (see the module docstring);
    lobe_scale: ``mi.Float`` = N(g, a, b) 2 pi / (g + 2) in (0, 1], the normalisation
    relative to Phong's (exactly 1 when a = 0). ``from_values`` computes it; a container
    built by hand must carry ``improved_phong_lobe_scale(g, a, b)``.
    """

    kd: mi.Color3f
    ks: mi.Color3f
    g: mi.Float
    a: mi.Float
    b: mi.Float
    c: mi.Float
    lobe_scale: mi.Float

    @classmethod
    def from_values(cls, kd, ks, g, a=0.0, b=0.0, c=0.0) -> ImprovedPhongParams:
        """Validated parameters from numbers: colours grey, 3 values or (n, 3), others scalar
        or (n,).

        The normalisation is computed once per distinct (g, a, b) in float64.
        """
        validate_improved_phong_parameters(kd, ks, g, a, b, c)
        rgb, s = _as_lanes({"kd": kd, "ks": ks}, {"g": g, "a": a, "b": b, "c": c})
        keys = np.stack([s["g"], s["a"], s["b"]], axis=1)
        unique, inverse = np.unique(keys, axis=0, return_inverse=True)
        scales = np.array([improved_phong_lobe_scale(*row) for row in unique])
        return cls(
            _color(rgb["kd"]),
            _color(rgb["ks"]),
            _float(s["g"]),
            _float(s["a"]),
            _float(s["b"]),
            _float(s["c"]),
            _float(scales[inverse.reshape(-1)]),
        )


# ----------------------------------------------------------------------------------------
# Normalisation of the improved lobe (numpy, float64)


def _lobe_shape(beta: np.ndarray, g: float, b: float) -> np.ndarray:
    """cos^g(beta) exp(-b (1 - cos beta)^(1/pi)), with 1 - cos(beta) = 2 sin^2(beta / 2)."""
    one_minus_cos = 2.0 * np.sin(0.5 * beta) ** 2
    shape = np.cos(beta) ** g
    if b > 0.0:
        shape = shape * np.exp(-b * one_minus_cos ** (1.0 / math.pi))
    return shape


def _beta_edges(theta_i: float, g: float, b: float) -> np.ndarray:
    """Segment edges in beta, graded geometrically from the lobe width out to where the lobe
    drops below 1e-12, with an edge where the cone starts to cross the horizon."""
    beta_max = min(0.5 * math.pi, math.acos(math.exp(math.log(_LOBE_CUTOFF) / g)))
    width = math.sqrt(2.0 / (g + 2.0))  # cos^g(beta) = exp(-1) near beta = sqrt(2 / g)
    if b > 0.0:  # b (1 - cos beta)^(1/pi) = 1 at beta = sqrt(2) b^(-pi/2), in logarithms
        log_width = 0.5 * math.log(2.0) - 0.5 * math.pi * math.log(b)
        width = min(width, math.exp(min(log_width, 0.0)))
    width = max(width, 1e-9)  # lobes narrower than this carry no measurable light
    edges = [0.0]
    edge = 0.25 * width
    while edge < beta_max:
        edges.append(edge)
        edge *= 2.0
    edges.append(beta_max)
    kink = 0.5 * math.pi - theta_i
    if 0.0 < kink < beta_max:
        edges.append(kink)
    return np.unique(edges)


@lru_cache(maxsize=1)
def _gauss_legendre():
    return np.polynomial.legendre.leggauss(_NODES_PER_SEGMENT)


def _lobe_albedos(thetas: np.ndarray, g: float, a: float, b: float) -> np.ndarray:
    """``improved_phong_lobe_albedo`` for several incidence angles in one numpy pass."""
    x, w = _gauss_legendre()
    betas, weights, thetas_at_node, starts = [], [], [], []
    count = 0
    for theta in thetas:
        edges = _beta_edges(float(theta), g, b)
        lo, hi = edges[:-1, None], edges[1:, None]
        betas.append((0.5 * (hi - lo) * x + 0.5 * (hi + lo)).reshape(-1))
        weights.append((0.5 * (hi - lo) * w).reshape(-1))
        thetas_at_node.append(np.full(betas[-1].size, theta))
        starts.append(count)
        count += betas[-1].size
    beta = np.concatenate(betas)
    theta_node = np.concatenate(thetas_at_node)
    # Azimuth integral of max(cos theta_o, 0) on the cone, see _azimuth_integral.
    big_a = np.cos(beta) * np.cos(theta_node)
    big_b = np.sin(beta) * np.sin(theta_node)
    cut = big_a < big_b
    ratio = np.where(cut, -big_a / np.where(cut, big_b, 1.0), -1.0)
    phi0 = np.arccos(np.clip(ratio, -1.0, 1.0))
    partial = 2.0 * (big_a * phi0 + np.sqrt(np.maximum(big_b**2 - big_a**2, 0.0)))
    azimuth = np.where(cut, partial, 2.0 * math.pi * big_a)
    integrand = np.concatenate(weights) * _lobe_shape(beta, g, b) * azimuth * np.sin(beta)
    lobe = (g + 2.0) / (2.0 * math.pi) * np.add.reduceat(integrand, starts)
    return lobe / np.maximum(np.cos(np.asarray(thetas, dtype=np.float64)), MU_MIN) ** a


def improved_phong_lobe_albedo(theta_i: float, g: float, a: float, b: float) -> float:
    """Directional albedo of the improved lobe with Phong's factor (g + 2) / (2 pi):

        A(theta_i) = integral of (g + 2) / (2 pi) cos^g(beta) exp(-b (1 - cos beta)^(1/pi))
                     / max(cos theta_i, MU_MIN)^a  cos(theta_o) d omega_o

    over the viewer hemisphere, in float64. Integrated in coordinates centred on the mirror
    direction: the azimuth in closed form (on the cone of half-angle beta around the mirror
    direction, cos(theta_o) = A + B cos(phi) with A = cos(beta) cos(theta_i) and
    B = sin(beta) sin(theta_i), whose positive part integrates to 2 pi A if A >= B and to
    2 (A phi0 + sqrt(B^2 - A^2)), phi0 = arccos(-A / B), otherwise), beta by Gauss-Legendre
    on segments graded to the lobe width (converged to ~1e-9 for g in [1, 1e5]).
    """
    return float(_lobe_albedos(np.array([theta_i], dtype=np.float64), g, a, b)[0])


@lru_cache(maxsize=4096)
def improved_phong_max_lobe_albedo(g: float, a: float, b: float) -> tuple[float, float]:
    """(A_max, theta_i at the maximum in radians) of ``improved_phong_lobe_albedo``.

    theta_i spans [0, 90 deg): a grid (dense up to arccos(MU_MIN), where the grazing factor
    stops growing) and a bounded Brent refinement around the best grid point.
    """
    g, a, b = float(g), float(a), float(b)
    theta_floor = math.acos(MU_MIN)
    grid = np.concatenate(
        [
            np.linspace(0.0, theta_floor, 49),
            theta_floor + (0.5 * math.pi - theta_floor) * np.array([0.25, 0.5, 0.75, 0.999]),
        ]
    )
    values = _lobe_albedos(grid, g, a, b)
    k = int(np.argmax(values))
    best_theta, best = float(grid[k]), float(values[k])
    lo, hi = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, grid.size - 1)])
    result = minimize_scalar(
        lambda t: -improved_phong_lobe_albedo(t, g, a, b),
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 1e-7},
    )
    if -result.fun > best:
        best_theta, best = float(result.x), float(-result.fun)
    return best, best_theta


def improved_phong_lobe_scale(g: float, a: float, b: float) -> float:
    """N(g, a, b) 2 pi / (g + 2): 1 when a = 0, else 1 / max(1, A_max (1 + ALBEDO_MARGIN))."""
    if a == 0.0:
        return 1.0
    a_max, _ = improved_phong_max_lobe_albedo(g, a, b)
    return 1.0 / max(1.0, a_max * (1.0 + ALBEDO_MARGIN))


def improved_phong_normalization(g: float, a: float, b: float) -> float:
    """Normalisation N(g, a, b) (sr^-1) of the improved lobe, float64.

    N = (g + 2) / (2 pi) when a = 0 (the exp factor is <= 1, so Phong's bound holds) and
    N = (g + 2) / (2 pi) / max(1, A_max (1 + 1e-3)) otherwise, with A_max from
    ``improved_phong_max_lobe_albedo``. The lobe's directional albedo is then <= 1 for
    every incidence angle.
    """
    return (g + 2.0) / (2.0 * math.pi) * improved_phong_lobe_scale(g, a, b)


# ----------------------------------------------------------------------------------------
# Dr.Jit evaluation and sampling


def _valid(wi, wo):
    return (wi.z > 0.0) & (wo.z > 0.0)


def _phong_lobe(wi, wo, g):
    """(g + 2) / (2 pi) cos^g(beta) and cos(beta), beta between wi and the mirror of wo."""
    cos_beta = dr.maximum(dr.dot(wi, mirror_local(wo)), 0.0)
    return (g + 2.0) * INV_TWO_PI * safe_power(cos_beta, g), cos_beta


def _mean(color):
    return (color.x + color.y + color.z) * (1.0 / 3.0)


def _diffuse_probability(kd, ks):
    mean_d, mean_s = _mean(kd), _mean(ks)
    total = mean_d + mean_s
    return dr.select(total > 0.0, mean_d / dr.maximum(total, 1e-30), 1.0)


def _mixture_pdf(wi, wo, p_diffuse, g):
    cos_beta = dr.dot(wi, mirror_local(wo))
    pdf = p_diffuse * cosine_hemisphere_pdf(wi) + (1.0 - p_diffuse) * phong_lobe_pdf(cos_beta, g)
    return dr.select(_valid(wi, wo), pdf, 0.0)


def _mixture_sample(wo, u_lobe, u2, p_diffuse, g):
    wi_diffuse = square_to_cosine_hemisphere(u2)
    wi_lobe = sample_phong_lobe(mirror_local(wo), u2, g)
    wi = dr.select(u_lobe < p_diffuse, wi_diffuse, wi_lobe)
    return wi, _mixture_pdf(wi, wo, p_diffuse, g)


def phong_eval_specular(wi, wo, params: PhongParams):
    """Lobe part ks (g + 2) / (2 pi) cos^g(beta) of the original Phong BRDF (Color3f, sr^-1)."""
    lobe, _ = _phong_lobe(wi, wo, params.g)
    return dr.select(_valid(wi, wo), params.ks * lobe, 0.0)


def phong_eval(wi, wo, params: PhongParams):
    """Original Phong BRDF kd / pi + ks (g + 2) / (2 pi) cos^g(beta) (Color3f, sr^-1).

    Zero where wi.z <= 0 or wo.z <= 0.
    """
    lobe, _ = _phong_lobe(wi, wo, params.g)
    return dr.select(_valid(wi, wo), params.kd * INV_PI + params.ks * lobe, 0.0)


def phong_eval_parts(wi, wo, params: PhongParams):
    """(diffuse, specular) parts of ``phong_eval`` (Color3f, sr^-1); their sum is the BRDF."""
    lobe, _ = _phong_lobe(wi, wo, params.g)
    valid = _valid(wi, wo)
    return dr.select(valid, params.kd * INV_PI, 0.0), dr.select(valid, params.ks * lobe, 0.0)


def phong_sample(wo, u_lobe, u2, params: PhongParams):
    """Light direction wi for the viewer direction wo, and its density (sr^-1).

    u_lobe (``mi.Float``) picks the diffuse part when < p_d = mean(kd) / (mean(kd) + mean(ks));
    u2 (``mi.Point2f``) places the direction within the chosen part. The density is the
    mixture's (``phong_pdf``) and 0 when wi falls below the horizon.
    """
    return _mixture_sample(wo, u_lobe, u2, _diffuse_probability(params.kd, params.ks), params.g)


def phong_pdf(wi, wo, params: PhongParams):
    """Density (sr^-1) with which ``phong_sample`` returns wi: the mixture
    p_d cos(theta_i) / pi + (1 - p_d) (g + 1) / (2 pi) cos^g(beta); 0 below the horizon."""
    return _mixture_pdf(wi, wo, _diffuse_probability(params.kd, params.ks), params.g)


def phong_diffuse_coefficient(params: PhongParams):
    """(kd_eq, exponent) with the diffuse part kd_eq / pi cos^exponent(theta_i): (kd, 0)."""
    return params.kd, dr.zeros(mi.Float, dr.width(params.g))


def _improved_lobe(wi, wo, params: ImprovedPhongParams):
    lobe, cos_beta = _phong_lobe(wi, wo, params.g)
    one_minus_cos = dr.maximum(1.0 - cos_beta, 0.0)
    shape = dr.exp(-params.b * safe_power(one_minus_cos, mi.Float(INV_PI)))
    grazing = safe_power(dr.maximum(wi.z, MU_MIN), params.a)
    return lobe * (params.lobe_scale * shape / grazing)


def improved_phong_eval_specular(wi, wo, params: ImprovedPhongParams):
    """Lobe part ks N cos^g(beta) exp(-b (1 - cos beta)^(1/pi)) / max(cos theta_i, MU_MIN)^a."""
    return dr.select(_valid(wi, wo), params.ks * _improved_lobe(wi, wo, params), 0.0)


def improved_phong_eval(wi, wo, params: ImprovedPhongParams):
    """Improved Phong BRDF (paper Eq. 17, reading of the module docstring), Color3f sr^-1.

    Zero where wi.z <= 0 or wo.z <= 0; equals ``phong_eval`` when a = b = c = 0.
    """
    diffuse = params.kd * (INV_PI * safe_power(dr.maximum(wi.z, 0.0), params.c))
    specular = params.ks * _improved_lobe(wi, wo, params)
    return dr.select(_valid(wi, wo), diffuse + specular, 0.0)


def improved_phong_eval_parts(wi, wo, params: ImprovedPhongParams):
    """(diffuse, specular) parts of ``improved_phong_eval`` (Color3f, sr^-1)."""
    valid = _valid(wi, wo)
    diffuse = params.kd * (INV_PI * safe_power(dr.maximum(wi.z, 0.0), params.c))
    specular = params.ks * _improved_lobe(wi, wo, params)
    return dr.select(valid, diffuse, 0.0), dr.select(valid, specular, 0.0)


def improved_phong_sample(wo, u_lobe, u2, params: ImprovedPhongParams):
    """Same mixture sampler as ``phong_sample`` (the cos^c factor is left to the weight)."""
    return _mixture_sample(wo, u_lobe, u2, _diffuse_probability(params.kd, params.ks), params.g)


def improved_phong_pdf(wi, wo, params: ImprovedPhongParams):
    """Density (sr^-1) of ``improved_phong_sample``, the mixture of ``phong_pdf``."""
    return _mixture_pdf(wi, wo, _diffuse_probability(params.kd, params.ks), params.g)


def improved_phong_diffuse_coefficient(params: ImprovedPhongParams):
    """(kd_eq, exponent) with the diffuse part kd_eq / pi cos^exponent(theta_i): (kd, c)."""
    return params.kd, params.c
