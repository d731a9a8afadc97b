"""The metrics of a BRDF fit, as the paper's Table 4: MSE, PSNR and mean angular error
(see :mod:`satsight.brdf.fit`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.brdf.measurements import BrdfMeasurements
from satsight.vectors import angle_between_rad

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
    if mse == 0.0:
        psnr = math.inf
    else:  # a table without a positive value has no peak: -inf dB
        psnr = 10.0 * math.log10(peak * peak / mse) if peak > 0.0 else -math.inf

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
            angles = angle_between_rad(meas_vec[complete], fit_vec[complete])
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
            errors.append(float(angle_between_rad(wo[k_meas], wo[k_fit])))
    peak_error = float(np.degrees(np.mean(errors))) if errors else math.nan

    if spectral is not None:
        primary, kind = spectral, "spectral angle between measured and fitted channel vectors"
    else:
        primary, kind = peak_error, "angle between measured and fitted specular peak directions"
    return FitMetrics(mse, psnr, peak, primary, kind, spectral, peak_error)
