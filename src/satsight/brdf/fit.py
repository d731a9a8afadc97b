"""Fitting the renderer's reflection models to measured BRDF tables.

``fit_brdf(measurements, model)`` finds the parameters of ``phong``, ``improved_phong`` or
``ggx`` (the float64 functions of ``satsight.brdf.models``, the renderer's own) that
minimise the squared difference to the measured f_r (sr^-1), weighted by 1 / sigma when the
table gives uncertainties, with ``scipy.optimize.least_squares`` (trust-region reflective,
box bounds). Colour / spectral channels share the shape parameters (g, a, b, c or M, R,
IOR) and have their own reflectances (kd, ks or base colour), as in the renderer.

Parametrisation, chosen so that every point inside the bounds is a physical, energy
conserving material (the directional albedo is <= 1 at every incidence angle):

* Phong and improved Phong: per channel the total reflectance t = kd + ks in [0, 1] and
  the specular fraction s = ks / t in [0, 1] (kd = t (1 - s), ks = t s), and
  ln g in [0, ln 1e4]. Improved: a in [0, 1], b in [0, 20], c in [0, 4] (the material
  library's ranges). The lobe normalisation N(g, a, b) keeps the lobe's albedo <= 1, so
  kd + ks <= 1 suffices.
* GGX: base colour per channel in [0, 1], metallic in [0, 1], roughness in
  [sqrt(1e-3), 1] (above the renderer's floor alpha = 1e-3), IOR in [1, 4], the range over
  which the renderer's white-furnace test finds albedo <= 1.

After the fit the directional albedo is checked by quadrature at incidence angles from 0
to 89 deg (``max_directional_albedo``) and a fit above 1 + ALBEDO_TOLERANCE is rejected.

Uncertainties: with the Jacobian J of the residuals in the fitted variables, the
covariance is (J^T J)^-1 when the table gives uncertainties (residuals divided by sigma),
and otherwise the heteroscedasticity-consistent "sandwich" estimate
(J^T J)^-1 J^T diag(r^2) J (J^T J)^-1 N / (N - P) (measurement noise usually grows with
the BRDF value, so a single residual variance would understate the uncertainty of the
parameters that the specular peak determines). It is carried to the physical parameters
with the Jacobian of the parametrisation. Near a bound the linearisation is poor: the
parameters at a bound are listed in the fit.

Metrics (the paper's Table 4, section 4.4, for a BRDF fit; ``fit_metrics``):

* MSE = mean((f_fit - f_meas)^2) over all measurements, in sr^-2.
* PSNR = 10 log10(peak^2 / MSE) dB with peak the largest measured value (inf for MSE 0).
* Angular error: with two or more channels measured at the same geometry, the mean over
  geometries of the angle between the measured and the fitted spectral vectors (the
  "spectral angle", insensitive to overall scale, sensitive to colour). With a single
  channel, the mean over incidence directions of the angle between the measured and the
  fitted specular peak directions, each the viewing direction with the largest value
  among the measured ones (per channel; sets whose measured values are all 0 are left
  out). Both are reported when available.

``fit_brdf_command`` is what ``satsight fit-brdf`` does: read, fit, write the YAML entry
and the plot, return a report.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from scipy.optimize import least_squares

from satsight.brdf.measurements import BrdfMeasurements, read_brdf_csv
from satsight.brdf.models import (
    MASKINGS,
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
_DIFF_STEP = 1e-6
_STARTS_OPTIMISED = 2


# ----------------------------------------------------------------------------------------
# Parametrisation


def _shared_names(model: str) -> tuple[str, ...]:
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
    return (*names, *_shared_names(model))


def _bounds(model: str, n: int) -> tuple[np.ndarray, np.ndarray]:
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


def _to_physical(model: str, u: np.ndarray, n: int) -> np.ndarray:
    """Physical parameter vector (order of ``parameter_names``) from the fitted variables."""
    if model == "ggx":
        return np.array(u, dtype=np.float64)
    t, s = u[:n], u[n : 2 * n]
    rest = np.array(u[2 * n :], dtype=np.float64)
    rest[0] = math.exp(rest[0])
    return np.concatenate([t * (1.0 - s), t * s, rest])


def _from_physical(model: str, p: np.ndarray, n: int) -> np.ndarray:
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
    for k, name in enumerate(_shared_names(model)):
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


# ----------------------------------------------------------------------------------------
# Metrics (paper Table 4)


@dataclass(frozen=True)
class FitMetrics:
    """Agreement of a fit with the measurements (definitions in the module docstring).

    mse_sr2: mean squared error (sr^-2); psnr_db: 10 log10(peak^2 / MSE); peak_per_sr: the
    largest measured value; angular_error_deg: the spectral angle with >= 2 channels, else
    the peak-direction error; spectral_angle_deg (None with one channel) and
    peak_direction_error_deg: both definitions.
    """

    mse_sr2: float
    psnr_db: float
    peak_per_sr: float
    angular_error_deg: float
    angular_error_kind: str
    spectral_angle_deg: float | None
    peak_direction_error_deg: float

    def as_dict(self) -> dict[str, float | str | None]:
        return {
            "mse_sr2": self.mse_sr2,
            "psnr_db": self.psnr_db,
            "peak_brdf_per_sr": self.peak_per_sr,
            "angular_error_deg": self.angular_error_deg,
            "angular_error_definition": self.angular_error_kind,
            "spectral_angle_deg": self.spectral_angle_deg,
            "peak_direction_error_deg": self.peak_direction_error_deg,
        }


def _angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle (rad) between rows of u and v (..., k), stable near 0 and pi."""
    nu = np.linalg.norm(u, axis=-1, keepdims=True)
    nv = np.linalg.norm(v, axis=-1, keepdims=True)
    a = u / np.where(nu > 0, nu, 1.0)
    b = v / np.where(nv > 0, nv, 1.0)
    return 2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def _group_keys(*angles_rad: np.ndarray) -> np.ndarray:
    """Integer group index per row for equal angle tuples (to 1e-7 rad)."""
    stacked = np.round(np.stack(angles_rad, axis=1) * 1e7).astype(np.int64)
    _, inverse = np.unique(stacked, axis=0, return_inverse=True)
    return inverse.reshape(-1)


def fit_metrics(measurements: BrdfMeasurements, fitted_per_sr: np.ndarray) -> FitMetrics:
    """MSE, PSNR and angular errors of fitted values (N,) against the measured ones."""
    measured = measurements.brdf_per_sr
    fitted = np.asarray(fitted_per_sr, dtype=np.float64)
    mse = float(np.mean((fitted - measured) ** 2))
    peak = float(np.max(measured))
    psnr = math.inf if mse == 0.0 else 10.0 * math.log10(peak * peak / mse)

    m = measurements
    # Spectral angle: geometries where every channel was measured.
    spectral = None
    if m.n_channels >= 2:
        geometry = _group_keys(m.theta_i_rad, m.phi_i_rad, m.theta_o_rad, m.phi_o_rad)
        n_geom = int(geometry.max()) + 1
        meas_vec = np.zeros((n_geom, m.n_channels))
        fit_vec = np.zeros((n_geom, m.n_channels))
        count = np.zeros((n_geom, m.n_channels), dtype=int)
        np.add.at(meas_vec, (geometry, m.channel), measured)
        np.add.at(fit_vec, (geometry, m.channel), fitted)
        np.add.at(count, (geometry, m.channel), 1)
        complete = np.all(count == 1, axis=1)
        complete &= (np.linalg.norm(meas_vec, axis=1) > 0) & (np.linalg.norm(fit_vec, axis=1) > 0)
        if np.any(complete):
            angles = _angle_between(meas_vec[complete], fit_vec[complete])
            spectral = float(np.degrees(np.mean(angles)))

    # Peak direction per incidence direction and channel.
    incidence = _group_keys(m.theta_i_rad, m.phi_i_rad)
    wo = m.wo()
    errors = []
    for group in np.unique(incidence):
        for ch in range(m.n_channels):
            rows = np.flatnonzero((incidence == group) & (m.channel == ch))
            if rows.size < 2 or not np.any(measured[rows] > 0.0):
                continue
            k_meas = rows[np.argmax(measured[rows])]
            k_fit = rows[np.argmax(fitted[rows])]
            errors.append(float(_angle_between(wo[k_meas], wo[k_fit])))
    peak_error = float(np.degrees(np.mean(errors))) if errors else math.nan

    if spectral is not None:
        primary, kind = spectral, "spectral angle between measured and fitted channel vectors"
    else:
        primary, kind = peak_error, "angle between measured and fitted specular peak directions"
    return FitMetrics(mse, psnr, peak, primary, kind, spectral, peak_error)


# ----------------------------------------------------------------------------------------
# The fit


@dataclass(frozen=True)
class BrdfFit:
    """A fitted reflection model.

    model: "phong", "improved_phong" or "ggx"; names / values / std: the physical
    parameters (``parameter_names`` order), their best values and 1-sigma uncertainties;
    covariance (P, P); channel_names, channel_kind: as in the measurements; masking: the
    GGX masking function; metrics: ``FitMetrics``; max_albedo (and its theta_i_deg): the
    largest directional albedo; at_bounds: parameters whose fitted variable is at a
    bound; cost: half the sum of squared weighted residuals; n_measurements; success,
    message: from the optimiser.
    """

    model: str
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    channel_names: tuple[str, ...]
    channel_kind: str
    masking: str
    metrics: FitMetrics
    max_albedo: float
    max_albedo_theta_deg: float
    at_bounds: tuple[str, ...]
    cost: float
    n_measurements: int
    reduced_chi2: float
    weighted: bool
    success: bool
    message: str
    source: dict = field(default_factory=dict)

    @property
    def parameters(self) -> dict[str, np.ndarray | float]:
        """Keyword arguments of the model function (per-channel (C,) arrays, shared floats)."""
        return unpack_parameters(self.model, self.values, len(self.channel_names))

    @property
    def parameter_std(self) -> dict[str, np.ndarray | float]:
        return unpack_parameters(self.model, self.std, len(self.channel_names))

    def evaluate(self, wi: np.ndarray, wo: np.ndarray, channel: np.ndarray) -> np.ndarray:
        """f_r (sr^-1) of the fitted model at direction pairs (N, 3) in channels (N,)."""
        return evaluate_model(self.model, self.parameters, wi, wo, channel, self.masking)


def _starts(model: str, measurements: BrdfMeasurements) -> list[np.ndarray]:
    """Physical starting points: reflectances from the median measured level, a few
    lobe widths."""
    n = measurements.n_channels
    level = np.array(
        [np.median(measurements.brdf_per_sr[measurements.channel == c]) for c in range(n)]
    )
    diffuse = np.clip(math.pi * level, 0.02, 0.8)
    starts = []
    if model == "ggx":
        for roughness in (0.1, 0.3, 0.6, 0.9):
            for metallic in (0.1, 0.8):
                base = np.clip(diffuse / (1.0 - metallic + 1e-3), 0.05, 0.95)
                starts.append(np.concatenate([base, [metallic, roughness, 1.5]]))
        return starts
    for g in (3.0, 30.0, 300.0, 3000.0):
        kd = diffuse
        ks = np.minimum(0.3, 0.99 - kd)
        shared = [g] if model == "phong" else [g, 0.3, 0.5, 0.5]
        starts.append(np.concatenate([kd, ks, shared]))
    return starts


def fit_brdf(
    measurements: BrdfMeasurements,
    model: str,
    masking: str = "schlick",
    check_energy: bool = True,
) -> BrdfFit:
    """Least-squares fit of a model's parameters to a measured table (module docstring).

    model: "phong", "improved_phong" or "ggx"; masking: GGX masking ("schlick", the
    paper's, or "smith"). Raises ``SatsightError`` for an unknown model, too few
    measurements, or a fit whose directional albedo exceeds 1 (check_energy).
    """
    if model not in FITTABLE_MODELS:
        raise SatsightError(
            f"unknown BRDF model '{model}'; use one of {', '.join(FITTABLE_MODELS)}"
        )
    if masking not in MASKINGS:
        raise SatsightError(f"unknown GGX masking '{masking}'; use one of {', '.join(MASKINGS)}")
    n = measurements.n_channels
    names = parameter_names(model, measurements.channel_names)
    if measurements.size <= len(names):
        raise SatsightError(
            f"{measurements.path}: {measurements.size} measurements cannot determine the "
            f"{len(names)} parameters of the {model} model; measure more geometries"
        )
    wi, wo, channel = measurements.wi(), measurements.wo(), measurements.channel
    measured = measurements.brdf_per_sr
    sigma = measurements.uncertainty_per_sr
    weight = 1.0 if sigma is None else 1.0 / sigma
    lo, hi = _bounds(model, n)

    def residuals(u: np.ndarray) -> np.ndarray:
        params = unpack_parameters(model, _to_physical(model, u, n), n)
        return (evaluate_model(model, params, wi, wo, channel, masking) - measured) * weight

    candidates = [
        np.clip(_from_physical(model, p, n), lo, hi) for p in _starts(model, measurements)
    ]
    costs = [float(np.sum(residuals(u) ** 2)) for u in candidates]
    order = np.argsort(costs)[:_STARTS_OPTIMISED]
    best = None
    for k in order:
        result = least_squares(
            residuals,
            candidates[k],
            bounds=(lo, hi),
            method="trf",
            x_scale="jac",
            diff_step=_DIFF_STEP,
            max_nfev=400 * len(names),
        )
        if best is None or result.cost < best.cost:
            best = result
    assert best is not None

    values = _to_physical(model, best.x, n)
    dof = measurements.size - len(names)
    reduced_chi2 = 2.0 * best.cost / dof
    jac = best.jac
    bread = np.linalg.pinv(jac.T @ jac)
    if sigma is not None:
        cov_u = bread
    else:  # heteroscedasticity-consistent (sandwich) estimate, HC1
        meat = (jac * best.fun[:, None] ** 2).T @ jac
        cov_u = bread @ meat @ bread * (measurements.size / dof)
    h = np.zeros((len(names), len(names)))
    for j in range(len(names)):
        step = 1e-7 * max(1.0, abs(best.x[j]))
        up, down = best.x.copy(), best.x.copy()
        up[j] += step
        down[j] -= step
        h[:, j] = (_to_physical(model, up, n) - _to_physical(model, down, n)) / (2.0 * step)
    covariance = h @ cov_u @ h.T
    std = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    at_bounds = tuple(
        _fitted_variable_names(model, measurements.channel_names)[j]
        for j in np.flatnonzero(best.active_mask)
    )
    params = unpack_parameters(model, values, n)
    fitted = evaluate_model(model, params, wi, wo, channel, masking)
    metrics = fit_metrics(measurements, fitted)
    if check_energy:
        max_albedo, theta_max = max_directional_albedo(model, params, masking)
        if max_albedo > 1.0 + ALBEDO_TOLERANCE:
            raise SatsightError(
                f"{measurements.path}: the fitted {model} parameters reflect more light than "
                f"they receive (directional albedo {max_albedo:.4f} at theta_i = "
                f"{theta_max:g} deg); this is a bug in the fit's bounds, please report it"
            )
    else:
        max_albedo, theta_max = math.nan, math.nan
    return BrdfFit(
        model=model,
        names=names,
        values=values,
        std=std,
        covariance=covariance,
        channel_names=measurements.channel_names,
        channel_kind=measurements.channel_kind,
        masking=masking,
        metrics=metrics,
        max_albedo=max_albedo,
        max_albedo_theta_deg=theta_max,
        at_bounds=at_bounds,
        cost=float(best.cost),
        n_measurements=measurements.size,
        reduced_chi2=reduced_chi2,
        weighted=sigma is not None,
        success=bool(best.success),
        message=str(best.message),
        source=_source(measurements),
    )


def _fitted_variable_names(model: str, channel_names: tuple[str, ...]) -> tuple[str, ...]:
    if model == "ggx":
        return parameter_names(model, channel_names)
    per_channel = [f"{p}[{c}]" for p in ("kd+ks", "ks/(kd+ks)") for c in channel_names]
    return (*per_channel, *_shared_names(model))


def _source(measurements: BrdfMeasurements) -> dict:
    path = measurements.path
    source: dict = {"csv": str(path)}
    if path.is_file():
        source["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    if measurements.metadata:
        source["provenance"] = dict(measurements.metadata)
    return source


# ----------------------------------------------------------------------------------------
# Material-library entry (YAML) and the command


def _is_rgb(channel_names: tuple[str, ...]) -> bool:
    return tuple(c.upper() for c in channel_names) == ("R", "G", "B")


def _channel_value(values: np.ndarray, channel_names: tuple[str, ...]):
    values = [float(v) for v in values]
    return values[0] if len(values) == 1 else values


def material_entry(fit: BrdfFit) -> dict:
    """The fit as a material-library entry: model, parameters (kd / kd_rgb, ks / ks_rgb, g,
    a, b, c, or base_color / base_color_rgb, metallic, roughness, ior, masking), their
    1-sigma uncertainties, channels, metrics, energy check, fit details and source."""
    suffix = "_rgb" if _is_rgb(fit.channel_names) else ""
    key = {"kd": "kd", "ks": "ks", "base": "base_color"}

    def section(values: dict) -> dict:
        out = {}
        for name, value in values.items():
            if isinstance(value, np.ndarray):
                out[key[name] + suffix] = _channel_value(value, fit.channel_names)
            else:
                out[name] = float(value)
        return out

    parameters = section(fit.parameters)
    if fit.model == "ggx":
        parameters["masking"] = fit.masking
    return {
        "model": fit.model,
        "parameters": parameters,
        "parameters_std": section(fit.parameter_std),
        "channels": {"kind": fit.channel_kind, "names": list(fit.channel_names)},
        "metrics": fit.metrics.as_dict(),
        "energy": {
            "max_directional_albedo": float(fit.max_albedo),
            "at_theta_i_deg": float(fit.max_albedo_theta_deg),
        },
        "fit": {
            "n_measurements": fit.n_measurements,
            "n_parameters": len(fit.names),
            "weighted_by_uncertainty": fit.weighted,
            "reduced_chi2": float(fit.reduced_chi2),
            "parameters_at_bounds": list(fit.at_bounds),
            "converged": fit.success,
            "optimizer_message": fit.message,
        },
        "source": fit.source,
        "library_brdf": library_brdf_block(fit),
    }


_LIBRARY_KEYS = {
    "metallic": "metallic",
    "roughness": "roughness",
    "ior": "ior",
    "g": "gloss_exponent_g",
    "a": "fresnel_exponent_a",
    "b": "lobe_decay_b",
    "c": "diffuse_exponent_c",
}


def library_brdf_block(fit: BrdfFit) -> dict:
    """The fitted shape parameters as entries ``{value, source}`` of a material-library
    ``brdf:`` block (``satsight.scene.material_library`` names: metallic, roughness, ior,
    gloss_exponent_g, fresnel_exponent_a, lobe_decay_b, diffuse_exponent_c); per-channel
    reflectances stay in ``parameters``."""
    where = fit.source.get("csv", "?")
    source = f"{fit.model} fit to {where}, PSNR {fit.metrics.psnr_db:.1f} dB (satsight.brdf.fit)"
    return {
        _LIBRARY_KEYS[name]: {"value": float(value), "source": source}
        for name, value in fit.parameters.items()
        if name in _LIBRARY_KEYS
    }


def write_fit_yaml(fit: BrdfFit, path: str | Path) -> Path:
    """Write ``material_entry(fit)`` as YAML."""
    path = Path(path)
    path.write_text(
        yaml.safe_dump(material_entry(fit), sort_keys=False, default_flow_style=None),
        encoding="utf-8",
    )
    return path


@dataclass(frozen=True)
class FitReport:
    """What ``fit_brdf_command`` did: the fit and the files it wrote."""

    fit: BrdfFit
    csv_path: Path
    yaml_path: Path
    plot_path: Path

    def table(self) -> str:
        """Plain-text summary: parameters with 1-sigma uncertainties, metrics, files."""
        fit = self.fit
        lines = [
            f"BRDF fit: {fit.model} to {self.csv_path} "
            f"({fit.n_measurements} measurements, channels: {', '.join(fit.channel_names)})",
            f"{'parameter':<22}{'value':>14}{'1-sigma':>14}",
        ]
        for name, value, std in zip(fit.names, fit.values, fit.std, strict=True):
            lines.append(f"{name:<22}{value:>14.6g}{std:>14.3g}")
        m = fit.metrics
        lines += [
            f"MSE {m.mse_sr2:.4g} sr^-2, PSNR {m.psnr_db:.2f} dB (peak {m.peak_per_sr:.4g} "
            f"sr^-1), angular error {m.angular_error_deg:.3f} deg ({m.angular_error_kind})",
            f"largest directional albedo {fit.max_albedo:.4f} (theta_i = "
            f"{fit.max_albedo_theta_deg:g} deg)",
        ]
        if fit.at_bounds:
            lines.append("at a bound (uncertainty not meaningful): " + ", ".join(fit.at_bounds))
        if not fit.success:
            lines.append(f"optimizer did not converge: {fit.message}")
        lines += [f"wrote {self.yaml_path}", f"wrote {self.plot_path}"]
        return "\n".join(lines)


def fit_brdf_command(
    csv_path: str | Path,
    model: str,
    out_dir: str | Path,
    masking: str = "schlick",
) -> FitReport:
    """``satsight fit-brdf CSV --model M --out DIR``: read the table, fit the model, write
    ``DIR/<csv stem>_<model>.yaml`` (``material_entry``) and
    ``DIR/<csv stem>_<model>_plane.png`` (measured and fitted BRDF in the plane of
    incidence), and return the report (prints nothing)."""
    from satsight.brdf.plot import plot_plane_of_incidence

    csv_path = Path(csv_path)
    measurements = read_brdf_csv(csv_path)
    fit = fit_brdf(measurements, model, masking=masking)
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise SatsightError(f"cannot create the output folder {out}: {err}") from None
    stem = f"{csv_path.stem}_{model}"
    yaml_path = write_fit_yaml(fit, out / f"{stem}.yaml")
    plot_path = plot_plane_of_incidence(
        measurements,
        fit.evaluate,
        out / f"{stem}_plane.png",
        title=f"{csv_path.name}: {model}, PSNR {fit.metrics.psnr_db:.1f} dB",
    )
    return FitReport(fit=fit, csv_path=csv_path, yaml_path=yaml_path, plot_path=plot_path)
