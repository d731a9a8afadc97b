"""Phong models fitted to a material's own GGX BRDF (model-to-model fits).

The materials are defined in the GGX metallic / roughness / IOR parameters (paper Eq.
18-20). ``fit_phong_to_ggx(material)`` samples that GGX BRDF (``brdf.models.ggx_brdf``, the
renderer's function, with the renderer's masking term) on a fixed set of geometries and
fits the improved Phong (Eq. 17) and the Phong (Eq. 16) models to it with
``brdf.fit.fit_brdf``, so that each Phong form is compared with the GGX model at its best
parameters instead of at a heuristic mapping. These are fits of one model to another, not
to measurements.

Geometries (the same for every material, except that the viewing grid follows the GGX lobe
width):

* incidence: ``N_INCIDENCE`` Gauss-Legendre nodes in mu_i = cos(theta_i) on
  [cos 85 deg, 1] (theta_i from about 3 to 84 deg), azimuth phi_i = 0;
* viewing: coordinates (beta, psi) around the mirror direction of wi, beta (the angle from
  the mirror direction) by Gauss-Legendre with ``NODES_PER_SEGMENT`` nodes on segments
  graded geometrically from w / 8 to pi (w = ``ggx_lobe_width_rad``, about 2 alpha), psi
  by the midpoint rule with ``N_AZIMUTH`` nodes on [0, pi] (every model is symmetric about
  the plane of incidence); directions below the horizon are left out. The grid covers the
  whole viewer hemisphere, in-plane and out-of-plane, and resolves narrow lobes.
* channels: R, G, B (the material's base colour per channel).

Weights (residual weight sqrt(W), passed to ``fit_brdf`` as uncertainty 1 / sqrt(W)):

    W = w_mu w_beta sin(beta) w_psi  *  cos^2(theta_i) cos(theta_o)

The first factor is the quadrature weight (solid angle of incidence and of viewing), so
the weighted sum of squared residuals approximates

    integral over wi, wo of (f_phong - f_ggx)^2 cos^2(theta_i) cos(theta_o) dw_o dw_i,

the mean squared radiance error, per unit irradiance, of a flat facet of random
orientation lit by a collimated source (radiance error = delta f cos(theta_i) E), averaged
over viewing directions in proportion to the facet's projected area (cos theta_o: the
pixels it covers). That is the error the ablation's image MSE measures for the Sun term.

``PhongModelFits`` holds both fits, as ``PhongCoefficients`` for ``Material.phong`` and
with the fit metrics (``brdf.metrics.FitMetrics`` on the grid, unweighted: PSNR against the
largest GGX value, spectral angle), ``weighted_relative_rms`` =
sqrt(sum W df^2 / sum W f^2), the relative radiance error in the weighting above, and
``weighted_spectral_angle_deg``: the angle between the GGX and fitted RGB vectors averaged
with weights W |f_ggx| (the unweighted spectral angle of ``FitMetrics`` counts the far
tails, where both values are negligible, as much as the highlight).

Fits are cached per material value set (base colour, metallic, roughness, IOR, masking):
the ablation asks once per part.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from satsight.brdf.fit import BrdfFit, fit_brdf
from satsight.brdf.measurements import BrdfMeasurements
from satsight.brdf.models import (
    MASKINGS,
    ggx_brdf,
    ggx_lobe_width_rad,
    graded_beta_nodes,
    mirror_about_normal,
    unit_vectors_from_angles,
)
from satsight.errors import SatsightError
from satsight.scene.materials import Material, PhongCoefficients

N_INCIDENCE = 6
MAX_THETA_I_DEG = 85.0
NODES_PER_SEGMENT = 3
N_AZIMUTH = 8
CHANNELS = ("R", "G", "B")
FIT_MODELS = ("improved_phong", "phong")


@dataclass(frozen=True)
class ReferenceGrid:
    """Direction pairs of the fit: wi, wo (N, 3) in the surface frame (normal +z) and the
    weight W (N,) of each pair (module docstring)."""

    wi: np.ndarray
    wo: np.ndarray
    weight: np.ndarray

    @property
    def size(self) -> int:
        return int(self.weight.size)


def reference_grid(lobe_width_rad: float) -> ReferenceGrid:
    """The fit's geometries and weights for a GGX lobe of angular width ``lobe_width_rad``
    around the mirror direction (module docstring)."""
    x, w = np.polynomial.legendre.leggauss(N_INCIDENCE)
    mu_lo = math.cos(math.radians(MAX_THETA_I_DEG))
    mu = 0.5 * (1.0 - mu_lo) * x + 0.5 * (1.0 + mu_lo)
    w_mu = 0.5 * (1.0 - mu_lo) * w
    beta, w_beta = graded_beta_nodes(lobe_width_rad, NODES_PER_SEGMENT)
    psi = (np.arange(N_AZIMUTH) + 0.5) * (math.pi / N_AZIMUTH)
    w_psi = 2.0 * math.pi / N_AZIMUTH  # [0, pi] stands for the symmetric full circle
    local = unit_vectors_from_angles(beta[:, None], psi[None, :])  # (n_beta, n_psi, 3)
    w_local = (w_beta[:, None] * w_psi * np.ones(psi.size)).ravel()
    local = local.reshape(-1, 3)
    wis, wos, weights = [], [], []
    for mu_k, w_k in zip(mu, w_mu, strict=True):
        wi = unit_vectors_from_angles(math.acos(mu_k), 0.0)
        axis = mirror_about_normal(wi)
        e2 = np.array([0.0, 1.0, 0.0])
        e1 = np.cross(e2, axis)
        wo = local[:, 0:1] * e1 + local[:, 1:2] * e2 + local[:, 2:3] * axis
        keep = wo[:, 2] > 1e-6
        wos.append(wo[keep])
        wis.append(np.broadcast_to(wi, wo[keep].shape))
        weights.append(w_k * w_local[keep] * mu_k**2 * wo[keep, 2])
    return ReferenceGrid(np.concatenate(wis), np.concatenate(wos), np.concatenate(weights))


def _angles(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    theta = np.arccos(np.clip(v[:, 2], -1.0, 1.0))
    phi = np.arctan2(v[:, 1], v[:, 0])
    return theta, phi


def ggx_reference_table(material: Material, masking: str = "schlick") -> BrdfMeasurements:
    """The material's GGX BRDF on ``reference_grid`` as a 3-channel (R, G, B) table whose
    ``uncertainty_per_sr`` is 1 / sqrt(W) (so ``fit_brdf`` weights residuals by sqrt(W))."""
    if masking not in MASKINGS:
        raise SatsightError(f"unknown GGX masking '{masking}'; use one of {', '.join(MASKINGS)}")
    grid = reference_grid(ggx_lobe_width_rad(material.roughness))
    n = grid.size
    base = np.asarray(material.base_color_rgb, dtype=np.float64)
    values = ggx_brdf(
        grid.wi[:, None, :],
        grid.wo[:, None, :],
        base,
        material.metallic,
        material.roughness,
        material.ior,
        masking,
    )  # (N, 3)
    theta_i, phi_i = _angles(grid.wi)
    theta_o, phi_o = _angles(grid.wo)
    weight = grid.weight / np.mean(grid.weight)  # scale-free; only ratios matter
    channels = len(CHANNELS)

    def per_channel(v: np.ndarray) -> np.ndarray:
        return np.repeat(v, channels)

    return BrdfMeasurements(
        path=Path(f"<GGX BRDF of material '{material.name}'>"),
        theta_i_rad=per_channel(theta_i),
        phi_i_rad=per_channel(phi_i),
        theta_o_rad=per_channel(theta_o),
        phi_o_rad=per_channel(phi_o),
        brdf_per_sr=values.reshape(-1),
        channel=np.tile(np.arange(channels), n),
        channel_names=CHANNELS,
        channel_kind="band",
        uncertainty_per_sr=per_channel(1.0 / np.sqrt(weight)),
        line_numbers=np.arange(n * channels) + 1,
        metadata={"material": material.name, "kind": "model-to-model: GGX reference"},
    )


@dataclass(frozen=True)
class ModelFit:
    """One Phong model fitted to a GGX material: ``coefficients`` for ``Material.phong``,
    the ``fit`` (``brdf.fit.BrdfFit``: metrics on the grid, energy check),
    ``weighted_relative_rms`` and ``weighted_spectral_angle_deg`` (module docstring)."""

    model: str
    coefficients: PhongCoefficients
    fit: BrdfFit
    weighted_relative_rms: float
    weighted_spectral_angle_deg: float

    def summary(self) -> dict:
        """The coefficients (kd, ks per channel, g, a, b, c) and the fit's metrics, JSON-ready."""
        c, m = self.coefficients, self.fit.metrics
        return {
            "kd_rgb": list(c.kd_rgb),
            "ks_rgb": list(c.ks_rgb),
            "g": c.gloss_exponent_g,
            "a": c.fresnel_exponent_a,
            "b": c.lobe_decay_b,
            "c": c.diffuse_exponent_c,
            "psnr_db": m.psnr_db,
            "spectral_angle_deg": m.spectral_angle_deg,
            "weighted_relative_rms": self.weighted_relative_rms,
            "weighted_spectral_angle_deg": self.weighted_spectral_angle_deg,
        }


@dataclass(frozen=True)
class PhongModelFits:
    """The improved Phong and Phong fits to one material's GGX BRDF (``fits[model]``)."""

    material: Material
    masking: str
    n_geometries: int
    fits: dict[str, ModelFit]

    def material_for(self, model: str) -> Material:
        """The material with ``phong`` set to the ``model`` fit's coefficients."""
        return dataclasses.replace(self.material, phong=self.fits[model].coefficients)


def _coefficients(fit: BrdfFit, material: Material) -> PhongCoefficients:
    p = fit.parameters
    kd = np.clip(np.asarray(p["kd"], dtype=np.float64), 0.0, 1.0)
    ks = np.clip(np.asarray(p["ks"], dtype=np.float64), 0.0, 1.0)
    ks = np.minimum(ks, 1.0 - kd)  # kd + ks = t <= 1 up to rounding
    improved = fit.model == "improved_phong"
    return PhongCoefficients(
        kd_rgb=tuple(kd),
        ks_rgb=tuple(ks),
        gloss_exponent_g=float(p["g"]),
        fresnel_exponent_a=float(p["a"]) if improved else 0.0,
        lobe_decay_b=float(p["b"]) if improved else 0.0,
        diffuse_exponent_c=float(p["c"]) if improved else 0.0,
        source=(
            f"{fit.model} fitted to the GGX BRDF of '{material.name}' (model-to-model, "
            f"satsight.brdf.reference_fit), PSNR {fit.metrics.psnr_db:.1f} dB"
        ),
    )


def _weighted_spectral_angle_deg(reference, fitted, weight) -> float:
    """Mean angle between the RGB vectors, weights W |f_ref| (rows are R, G, B per pair)."""
    ref = reference.reshape(-1, len(CHANNELS))
    fit = fitted.reshape(-1, len(CHANNELS))
    w = weight.reshape(-1, len(CHANNELS))[:, 0] * np.linalg.norm(ref, axis=1)
    norms = np.linalg.norm(ref, axis=1) * np.linalg.norm(fit, axis=1)
    used = norms > 0.0
    if not np.any(used) or np.sum(w[used]) == 0.0:
        return 0.0
    cross = np.linalg.norm(np.cross(ref[used], fit[used]), axis=1)
    angle = np.degrees(np.arctan2(cross, np.sum(ref[used] * fit[used], axis=1)))
    return float(np.sum(w[used] * angle) / np.sum(w[used]))


@lru_cache(maxsize=256)
def _fit_cached(
    base: tuple[float, float, float], metallic: float, roughness: float, ior: float, masking: str
) -> tuple[int, dict[str, tuple[BrdfFit, float, float]]]:
    material = Material("reference", base, metallic, roughness, ior)
    table = ggx_reference_table(material, masking)
    weight = 1.0 / table.uncertainty_per_sr**2
    reference = table.brdf_per_sr
    norm = float(np.sum(weight * reference**2))
    out = {}
    for model in FIT_MODELS:
        fit = fit_brdf(table, model, masking=masking)
        fitted = fit.evaluate(table.wi(), table.wo(), table.channel)
        error = float(np.sum(weight * (fitted - reference) ** 2))
        rms = math.sqrt(error / norm) if norm > 0.0 else 0.0
        out[model] = (fit, rms, _weighted_spectral_angle_deg(reference, fitted, weight))
    return table.size // len(CHANNELS), out


def fit_phong_to_ggx(material: Material, masking: str = "schlick") -> PhongModelFits:
    """Fit improved Phong and Phong to ``material``'s GGX BRDF (module docstring).

    masking: the GGX masking term of the reference ("schlick", the renderer's default and
    the paper's, or "smith"). Cached per (base colour, metallic, roughness, IOR, masking).
    """
    n_geometries, fits = _fit_cached(
        tuple(material.base_color_rgb),
        float(material.metallic),
        float(material.roughness),
        float(material.ior),
        masking,
    )
    return PhongModelFits(
        material=material,
        masking=masking,
        n_geometries=n_geometries,
        fits={
            model: ModelFit(model, _coefficients(fit, material), fit, rms, angle)
            for model, (fit, rms, angle) in fits.items()
        },
    )
