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

Modules: ``parameters`` (names, bounds, transform, evaluation, energy check), ``metrics``,
this one (the fit), ``fit_files`` (the YAML entry, and ``fit_brdf_command``, what
``satsight fit-brdf`` does: read, fit, write the YAML entry and the plot, return a
report).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from satsight.brdf.measurements import BrdfMeasurements
from satsight.brdf.metrics import FitMetrics, fit_metrics
from satsight.brdf.models import (
    MASKINGS,
)
from satsight.brdf.parameters import (
    ALBEDO_TOLERANCE,
    FITTABLE_MODELS,
    evaluate_model,
    from_physical,
    max_directional_albedo,
    parameter_bounds,
    parameter_names,
    shared_parameter_names,
    to_physical,
    unpack_parameters,
)
from satsight.errors import SatsightError

_DIFF_STEP = 1e-6
_STARTS_OPTIMISED = 2


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
    paper's, or "smith"). Raises ``SatsightError`` for an unknown model, a degenerate table
    (``check_table``), too few measurements, or a fit whose directional albedo exceeds 1
    (check_energy).
    """
    if model not in FITTABLE_MODELS:
        raise SatsightError(
            f"unknown BRDF model '{model}'; use one of {', '.join(FITTABLE_MODELS)}"
        )
    if masking not in MASKINGS:
        raise SatsightError(f"unknown GGX masking '{masking}'; use one of {', '.join(MASKINGS)}")
    n = measurements.n_channels
    names = parameter_names(model, measurements.channel_names)
    check_table(measurements)
    if measurements.size <= len(names):
        raise SatsightError(
            f"{measurements.path}: {measurements.size} measurements cannot determine the "
            f"{len(names)} parameters of the {model} model; measure more geometries"
        )
    distinct = _distinct_rows(measurements)
    if distinct <= len(names):
        raise SatsightError(
            f"{measurements.path}: the {measurements.size} rows hold only {distinct} distinct "
            f"(geometry, channel) measurements, which cannot determine the {len(names)} "
            f"parameters of the {model} model (repeating a geometry adds no information about "
            "the lobe's shape); measure more incidence and viewing angles"
        )
    wi, wo, channel = measurements.wi(), measurements.wo(), measurements.channel
    measured = measurements.brdf_per_sr
    sigma = measurements.uncertainty_per_sr
    weight = 1.0 if sigma is None else 1.0 / sigma
    lo, hi = parameter_bounds(model, n)

    def residuals(u: np.ndarray) -> np.ndarray:
        params = unpack_parameters(model, to_physical(model, u, n), n)
        return (evaluate_model(model, params, wi, wo, channel, masking) - measured) * weight

    candidates = [np.clip(from_physical(model, p, n), lo, hi) for p in _starts(model, measurements)]
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

    values = to_physical(model, best.x, n)
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
        h[:, j] = (to_physical(model, up, n) - to_physical(model, down, n)) / (2.0 * step)
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


def _geometry_keys(measurements: BrdfMeasurements) -> np.ndarray:
    """(N,) integer index of each row's geometry: equal direction pairs (wi, wo) to 1e-9,
    so that phi = 0 and 360 deg, or any phi at theta = 0, are the same geometry."""
    directions = np.concatenate([measurements.wi(), measurements.wo()], axis=1)
    rounded = np.round(directions * 1e9).astype(np.int64)
    _, inverse = np.unique(rounded, axis=0, return_inverse=True)
    return inverse.reshape(-1)


def _distinct_rows(measurements: BrdfMeasurements) -> int:
    """The number of distinct (geometry, channel) pairs of a table."""
    keys = np.stack([_geometry_keys(measurements), measurements.channel], axis=1)
    return len(np.unique(keys, axis=0))


def _line(measurements: BrdfMeasurements, row: int) -> str:
    """', line L' for a row read from a file, else ', row R' (0-based)."""
    lines = measurements.line_numbers
    if lines.size > row and lines[row] > 0:
        return f", line {int(lines[row])}"
    return f", row {row}"


def check_table(measurements: BrdfMeasurements) -> None:
    """Refuse a table that no model can be fitted to, with one line naming the file and
    what is wrong: no rows, a non-finite angle or BRDF value (NaN, inf), no positive BRDF
    value at all (no reflected light: every model fits it with zero reflectance and an
    undetermined lobe), or a single measured geometry (one pair of incidence and viewing
    directions: the lobe's shape is undetermined). Small negative values (noise after a
    background subtraction) are allowed here; ``read_brdf_csv`` refuses them in files."""
    m = measurements
    if m.size == 0:
        raise SatsightError(f"{m.path}: the table has no measurements")
    columns = {
        "theta_i_deg": m.theta_i_rad,
        "phi_i_deg": m.phi_i_rad,
        "theta_o_deg": m.theta_o_rad,
        "phi_o_deg": m.phi_o_rad,
        "brdf_per_sr": m.brdf_per_sr,
    }
    for name, values in columns.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise SatsightError(
                f"{m.path}{_line(m, int(bad[0]))}: {name} is {values[bad[0]]} ({bad.size} "
                "non-finite value(s) in the table); give finite numbers"
            )
    if not np.any(m.brdf_per_sr > 0.0):
        raise SatsightError(
            f"{m.path}: every one of the {m.size} brdf_per_sr values is 0, so there is no "
            "reflected light to fit; check that the column holds the BRDF in sr^-1"
        )
    if int(_geometry_keys(m).max()) == 0:
        raise SatsightError(
            f"{m.path}: all {m.size} rows measure one geometry (theta_i = "
            f"{math.degrees(m.theta_i_rad[0]):g}, phi_i = {math.degrees(m.phi_i_rad[0]):g}, "
            f"theta_o = {math.degrees(m.theta_o_rad[0]):g}, phi_o = "
            f"{math.degrees(m.phi_o_rad[0]):g} deg), which cannot show the shape of the "
            "reflection lobe; measure several incidence and viewing angles"
        )


def _fitted_variable_names(model: str, channel_names: tuple[str, ...]) -> tuple[str, ...]:
    if model == "ggx":
        return parameter_names(model, channel_names)
    per_channel = [f"{p}[{c}]" for p in ("kd+ks", "ks/(kd+ks)") for c in channel_names]
    return (*per_channel, *shared_parameter_names(model))


def _source(measurements: BrdfMeasurements) -> dict:
    path = measurements.path
    source: dict = {"csv": str(path)}
    if path.is_file():
        source["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    if measurements.metadata:
        source["provenance"] = dict(measurements.metadata)
    return source
