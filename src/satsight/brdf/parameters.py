"""The fitted models' parameters: names per model, bounds that keep them physical, the
transform the optimiser works in, evaluation, and the energy check (see
:mod:`satsight.brdf.fit`)."""

from __future__ import annotations

import math

import numpy as np

from satsight.brdf.models import (
    MIN_GGX_ALPHA,
    directional_albedo,
    ggx_brdf,
    ggx_lobe_width_rad,
    improved_phong_brdf,
    phong_brdf,
    phong_lobe_width_rad,
)
from satsight.errors import SatsightError
from satsight.scene.materials import (
    MAX_DIFFUSE_EXPONENT_C,
    MAX_GLOSS_EXPONENT,
    MAX_LOBE_DECAY_B,
    MIN_GLOSS_EXPONENT,
)

FITTABLE_MODELS = ("phong", "improved_phong", "ggx")
MAX_IOR = 4.0
MIN_ROUGHNESS = math.sqrt(MIN_GGX_ALPHA)
ALBEDO_TOLERANCE = 2e-3  # quadrature error of ``directional_albedo`` with margin
ALBEDO_CHECK_THETAS_DEG = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 85.0, 89.0)


# ----------------------------------------------------------------------------------------
# Parametrisation


def shared_parameter_names(model: str) -> tuple[str, ...]:
    return {
        "phong": ("g",),
        "improved_phong": ("g", "a", "b", "c"),
        "ggx": ("metallic", "roughness", "ior"),
    }[model]


def _channel_names(model: str) -> tuple[str, ...]:
    return ("base",) if model == "ggx" else ("kd", "ks")


def parameter_names(model: str, channel_names: tuple[str, ...]) -> tuple[str, ...]:
    """Names of the physical parameters in the order of ``BrdfFit.values``: per-channel
    ones as ``kd[R]``, then the shared ones."""
    names = [f"{p}[{c}]" for p in _channel_names(model) for c in channel_names]
    return (*names, *shared_parameter_names(model))


def parameter_bounds(model: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    if model == "ggx":
        lo = [0.0] * n + [0.0, MIN_ROUGHNESS, 1.0]
        hi = [1.0] * n + [1.0, 1.0, MAX_IOR]
    else:
        lo = [0.0] * (2 * n) + [math.log(MIN_GLOSS_EXPONENT)]
        hi = [1.0] * (2 * n) + [math.log(MAX_GLOSS_EXPONENT)]
        if model == "improved_phong":
            lo += [0.0, 0.0, 0.0]
            hi += [1.0, MAX_LOBE_DECAY_B, MAX_DIFFUSE_EXPONENT_C]
    return np.array(lo), np.array(hi)


def to_physical(model: str, u: np.ndarray, n: int) -> np.ndarray:
    """Physical parameter vector (order of ``parameter_names``) from the fitted variables."""
    if model == "ggx":
        return np.array(u, dtype=np.float64)
    t, s = u[:n], u[n : 2 * n]
    rest = np.array(u[2 * n :], dtype=np.float64)
    rest[0] = math.exp(rest[0])
    return np.concatenate([t * (1.0 - s), t * s, rest])


def from_physical(model: str, p: np.ndarray, n: int) -> np.ndarray:
    if model == "ggx":
        return np.array(p, dtype=np.float64)
    kd, ks = p[:n], p[n : 2 * n]
    t = kd + ks
    s = np.where(t > 0.0, ks / np.where(t > 0.0, t, 1.0), 0.5)
    rest = np.array(p[2 * n :], dtype=np.float64)
    rest[0] = math.log(rest[0])
    return np.concatenate([t, s, rest])


def unpack_parameters(model: str, values: np.ndarray, n: int) -> dict[str, np.ndarray | float]:
    """Physical parameter vector -> keyword arguments of the model function (per-channel
    values as (n,) arrays, shared ones as floats)."""
    values = np.asarray(values, dtype=np.float64)
    out: dict[str, np.ndarray | float] = {}
    for k, name in enumerate(_channel_names(model)):
        out[name] = values[k * n : (k + 1) * n]
    offset = len(_channel_names(model)) * n
    for k, name in enumerate(shared_parameter_names(model)):
        out[name] = float(values[offset + k])
    return out


def evaluate_model(
    model: str,
    params: dict[str, np.ndarray | float],
    wi: np.ndarray,
    wo: np.ndarray,
    channel: np.ndarray,
    masking: str = "schlick",
) -> np.ndarray:
    """f_r (sr^-1) of the model at direction pairs wi, wo (N, 3), each pair in its channel
    (N,) int (per-channel parameters are picked per row)."""
    per_row = {
        k: (np.asarray(v)[channel] if isinstance(v, np.ndarray) else v) for k, v in params.items()
    }
    if model == "phong":
        return phong_brdf(wi, wo, per_row["kd"], per_row["ks"], per_row["g"])
    if model == "improved_phong":
        return improved_phong_brdf(
            wi,
            wo,
            per_row["kd"],
            per_row["ks"],
            per_row["g"],
            per_row["a"],
            per_row["b"],
            per_row["c"],
        )
    if model == "ggx":
        return ggx_brdf(
            wi,
            wo,
            per_row["base"],
            per_row["metallic"],
            per_row["roughness"],
            per_row["ior"],
            masking,
        )
    raise SatsightError(f"unknown BRDF model '{model}'; use one of {', '.join(FITTABLE_MODELS)}")


def lobe_width_rad(model: str, params: dict[str, np.ndarray | float]) -> float:
    """Angular width of the model's specular lobe (for the albedo quadrature)."""
    if model == "ggx":
        return ggx_lobe_width_rad(float(params["roughness"]))
    width = phong_lobe_width_rad(float(params["g"]))
    b = float(params.get("b", 0.0))
    if b > 1.0:  # exp(-b (1 - cos beta)^(1/pi)) falls to 1/e at beta = sqrt(2) b^(-pi/2)
        width = min(width, math.sqrt(2.0) * b ** (-0.5 * math.pi))
    return width


def max_directional_albedo(
    model: str,
    params: dict[str, np.ndarray | float],
    masking: str = "schlick",
    thetas_deg=ALBEDO_CHECK_THETAS_DEG,
) -> tuple[float, float]:
    """(largest directional albedo over channels and incidence angles, its theta_i in deg),
    by the quadrature of ``satsight.brdf.models.directional_albedo``."""
    channel_values = {k: v for k, v in params.items() if isinstance(v, np.ndarray)}
    n = len(next(iter(channel_values.values())))
    channel = np.arange(n)

    def brdf(wi, wo):
        shape = wi.shape[:-1]
        wi_c = np.broadcast_to(wi[..., None, :], (*shape, n, 3))
        wo_c = np.broadcast_to(wo[..., None, :], (*shape, n, 3))
        ch = np.broadcast_to(channel, (*shape, n))
        return evaluate_model(model, params, wi_c, wo_c, ch, masking)

    width = lobe_width_rad(model, params)
    best, best_theta = -math.inf, 0.0
    for theta in thetas_deg:
        value = float(np.max(directional_albedo(brdf, math.radians(theta), width)))
        if value > best:
            best, best_theta = value, float(theta)
    return best, best_theta
