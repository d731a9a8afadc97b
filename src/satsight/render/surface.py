"""Per-part reflection models for the renderer: one BRDF model, parameters per part.

``SurfaceModel`` turns the target's materials into per-part Dr.Jit tables for the chosen
model (``RenderSettings.brdf``) and, at a hit, gathers the part's parameters and calls the
model's evaluation, sampling and diffuse-kernel functions (``satsight.render.ggx``,
``satsight.render.phong``). Directions are in the local shading frame (normal +z), ``wi``
towards the light and ``wo`` towards the viewer.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from satsight.lighting import sh
from satsight.render import ggx, phong
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material


def _phong_tables(materials: Sequence[Material]) -> dict[str, np.ndarray]:
    return {
        "kd": np.array([m.phong_kd_rgb for m in materials]),
        "ks": np.array([m.ks_rgb for m in materials]),
        "g": np.array([m.phong_gloss_exponent for m in materials]),
    }


def regularized(material: Material, min_roughness: float) -> Material:
    """The material with its roughness raised to ``min_roughness`` (and an explicit Phong
    gloss exponent capped at the matching value); unchanged when already rougher."""
    if material.roughness >= min_roughness:
        return material
    rougher = dataclasses.replace(material, roughness=min_roughness, gloss_exponent_g=None)
    if material.gloss_exponent_g is not None:
        cap = rougher.phong_gloss_exponent
        rougher = dataclasses.replace(rougher, gloss_exponent_g=min(material.gloss_exponent_g, cap))
    return rougher


class SurfaceModel:
    """The reflection model of every part of a target.

    materials: one per part, in part-index order. settings: the model (``brdf``) and, for
    GGX, its masking term.
    """

    def __init__(self, materials: Sequence[Material], settings: RenderSettings) -> None:
        import mitsuba as mi

        self._mi = mi
        self.model = settings.brdf
        self.materials = list(materials)
        if self.model == "ggx":
            self._params = ggx.GGXParams.from_values(
                np.array([m.base_color_rgb for m in materials]),
                np.array([m.metallic for m in materials]),
                np.array([m.roughness for m in materials]),
                np.array([m.ior for m in materials]),
                settings.ggx_masking,
            )
        elif self.model == "phong":
            t = _phong_tables(materials)
            self._params = phong.PhongParams.from_values(t["kd"], t["ks"], t["g"])
        else:
            t = _phong_tables(materials)
            self._params = phong.ImprovedPhongParams.from_values(
                t["kd"],
                t["ks"],
                t["g"],
                np.array([m.fresnel_exponent_a for m in materials]),
                np.array([m.lobe_decay_b for m in materials]),
                np.array([m.diffuse_exponent_c for m in materials]),
            )
        self._functions = {
            "ggx": (ggx.ggx_eval_parts, ggx.ggx_sample, None),
            "phong": (phong.phong_eval_parts, phong.phong_sample, phong.phong_diffuse_coefficient),
            "improved_phong": (
                phong.improved_phong_eval_parts,
                phong.improved_phong_sample,
                phong.improved_phong_diffuse_coefficient,
            ),
        }[self.model]

    def evaluate_tables(self) -> None:
        """Evaluate the per-part tables now, so that frames do not re-trace them."""
        import drjit as dr

        fields = [getattr(self._params, k) for k in self._field_names()]
        dr.eval(*fields)

    def _field_names(self) -> list[str]:
        return [
            f.name
            for f in dataclasses.fields(self._params)
            if not isinstance(getattr(self._params, f.name), str)
        ]

    def at(self, part, active):
        """The model's parameter container with each field gathered for the lanes' parts;
        gather once per surface hit and pass it to the calls below."""
        import drjit as dr

        changes = {}
        for name in self._field_names():
            table = getattr(self._params, name)
            changes[name] = dr.gather(type(table), table, part, active)
        return dataclasses.replace(self._params, **changes)

    # --- what the integrator calls ------------------------------------------------------
    def eval_parts(self, params, wi, wo):
        """(diffuse, specular) parts of f_r(wi, wo), sr^-1 per channel (Color3f each)."""
        return self._functions[0](wi, wo, params)

    def sample(self, params, wo, u_lobe, u2):
        """A light direction wi for viewer direction wo, and its pdf (solid angle)."""
        return self._functions[1](wo, u_lobe, u2, params)

    def pdf(self, params, wi, wo):
        """Solid-angle density with which ``sample`` picks wi for viewer direction wo."""
        function = {
            "ggx": ggx.ggx_pdf,
            "phong": phong.phong_pdf,
            "improved_phong": phong.improved_phong_pdf,
        }[self.model]
        return function(wi, wo, params)

    def diffuse_coefficient(self, params, wo):
        """kd_eq (Color3f) for viewer direction wo: the diffuse part is kd_eq / pi times the
        part's zonal kernel of theta_i (see ``diffuse_band_factors``) over cos(theta_i)."""
        if self.model == "ggx":
            kd, _ = ggx.ggx_diffuse_coefficient(params, wo)
        else:
            kd, _ = self._functions[2](params)
        return kd

    def diffuse_band_factors(self, l_max: int) -> np.ndarray:
        """(parts, l_max + 1) Funk-Hecke factors of each part's diffuse kernel k(cos theta_i).

        The unshadowed diffuse radiance is kd_eq / pi * sum_lm factor_l L_lm Y_lm(n), exact
        for a zonal kernel: max(t, 0) (Lambert, Phong: the factors are the clamped-cosine
        A_l of the irradiance), (1 - F_d(t)) max(t, 0) for GGX (light entering through the
        dielectric interface), max(t, 0)^(1 + c) for the improved Phong diffuse term.
        """
        keys = []
        for m in self.materials:
            if self.model == "ggx":
                keys.append(("fresnel", m.ior if m.metallic < 1.0 else 1.0))
            elif self.model == "improved_phong":
                keys.append(("power", 1.0 + m.diffuse_exponent_c))
            else:
                keys.append(("power", 1.0))
        rows = {}
        for key in set(keys):
            kind, value = key
            if key in (("power", 1.0), ("fresnel", 1.0)):
                rows[key] = sh.clamped_cosine_coeffs(l_max)
            elif kind == "power":
                rows[key] = sh.zonal_kernel_coeffs(
                    lambda t, p=value: np.maximum(t, 0.0) ** p, l_max
                )
            else:
                rows[key] = sh.zonal_kernel_coeffs(ggx.ggx_diffuse_kernel(value), l_max)
        return np.array([rows[key] for key in keys])
