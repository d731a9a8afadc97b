"""Measured against fitted BRDF in the plane of incidence (matplotlib, Agg canvas).

One panel per channel (up to ``MAX_PANELS``), one colour per incidence angle: the
measurements in the plane of incidence as markers, the model as a line. The abscissa is the
signed viewing angle: theta_o on the forward (specular) side of the normal, where
phi_o = phi_i + 180 deg, and -theta_o on the side of the source (phi_o = phi_i). A row is in
the plane when |sin(phi_o - phi_i)| < 1e-3 or theta_o = 0.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from satsight.brdf.measurements import BrdfMeasurements
from satsight.brdf.models import unit_vectors_from_angles

MAX_PANELS = 6
_IN_PLANE_SIN = 1e-3
_CURVE_POINTS = 361

BrdfFunction = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""f(wi (N, 3), wo (N, 3), channel (N,) int) -> f_r (N,) in sr^-1."""


def in_plane_signed_theta_o_deg(m: BrdfMeasurements) -> tuple[np.ndarray, np.ndarray]:
    """(mask of rows in the plane of incidence, signed viewing angle in degrees: + on the
    specular side, - on the source side)."""
    dphi = m.phi_o_rad - m.phi_i_rad
    in_plane = (np.abs(np.sin(dphi)) < _IN_PLANE_SIN) | (m.theta_o_rad == 0.0)
    forward = np.cos(dphi) < 0.0
    signed = np.where(forward, 1.0, -1.0) * np.degrees(m.theta_o_rad)
    return in_plane, signed


def plot_plane_of_incidence(
    measurements: BrdfMeasurements,
    model: BrdfFunction,
    path: str | Path,
    title: str = "",
) -> Path:
    """Write a PNG of measured (markers) and modelled (lines) BRDF in the plane of incidence,
    one panel per channel, one colour per incidence angle; returns the path."""
    m = measurements
    in_plane, signed = in_plane_signed_theta_o_deg(m)
    n_panels = min(m.n_channels, MAX_PANELS)
    cols = min(n_panels, 3)
    rows = math.ceil(n_panels / cols)
    fig = Figure(figsize=(4.2 * cols, 3.4 * rows), constrained_layout=True)
    FigureCanvasAgg(fig)
    theta_i_deg = np.round(np.degrees(m.theta_i_rad), 2)
    incidences = np.unique(theta_i_deg[in_plane])
    cmap = colormaps["viridis"]
    colours = [cmap(x) for x in np.linspace(0.0, 0.9, max(len(incidences), 1))]
    x_curve = np.linspace(-89.5, 89.5, _CURVE_POINTS)
    for panel in range(n_panels):
        ax = fig.add_subplot(rows, cols, panel + 1)
        rows_ch = in_plane & (m.channel == panel)
        positive = []
        for colour, theta in zip(colours, incidences, strict=False):
            sel = rows_ch & (theta_i_deg == theta)
            if not np.any(sel):
                continue
            order = np.argsort(signed[sel])
            ax.plot(
                signed[sel][order],
                m.brdf_per_sr[sel][order],
                "o",
                ms=3,
                color=colour,
                label=f"{theta:g}°",
            )
            phi_i = float(np.mean(m.phi_i_rad[sel]))
            wi = np.broadcast_to(
                unit_vectors_from_angles(math.radians(theta), phi_i), (x_curve.size, 3)
            )
            phi_o = np.where(x_curve >= 0.0, phi_i + math.pi, phi_i)
            wo = unit_vectors_from_angles(np.radians(np.abs(x_curve)), phi_o)
            curve = model(wi, wo, np.full(x_curve.size, panel))
            ax.plot(x_curve, curve, "-", lw=1.2, color=colour)
            positive.append(m.brdf_per_sr[sel][m.brdf_per_sr[sel] > 0])
            positive.append(curve[curve > 0])
        values = np.concatenate(positive) if positive else np.zeros(0)
        if values.size and values.max() > 100.0 * values.min():
            ax.set_yscale("log")
        ax.set_xlim(-90, 90)
        ax.set_xlabel("θo in the plane of incidence (deg, + specular side)", fontsize=8)
        ax.set_ylabel("BRDF (sr$^{-1}$)")
        ax.set_title(f"{m.channel_kind} {m.channel_names[panel]}", fontsize=9)
        ax.grid(True, alpha=0.3)
        if panel == 0 and len(incidences):
            ax.legend(title="θi", fontsize=7, title_fontsize=7)
        if not np.any(rows_ch):
            ax.text(0.5, 0.5, "no in-plane measurements", ha="center", transform=ax.transAxes)
    if title:
        fig.suptitle(title, fontsize=10)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path
