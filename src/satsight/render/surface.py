"""Per-part reflection models for the renderer: one BRDF model, parameters per part.

``SurfaceModel`` turns the target's materials into per-part Dr.Jit tables for the chosen
model (``RenderSettings.brdf``) and, at a hit, gathers the part's parameters and calls the
model's evaluation, sampling and diffuse-kernel functions (``satsight.render.ggx``,
``satsight.render.phong``). Directions are in the local shading frame (normal +z), ``wi``
towards the light and ``wo`` towards the viewer.
"""

from __future__ import annotations

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
            "ggx": (
                ggx.ggx_eval,
                ggx.ggx_eval_specular,
                ggx.ggx_sample,
                ggx.ggx_diffuse_coefficient,
            ),
            "phong": (
                phong.phong_eval,
                phong.phong_eval_specular,
                phong.phong_sample,
                phong.phong_diffuse_coefficient,
            ),
            "improved_phong": (
                phong.improved_phong_eval,
                phong.improved_phong_eval_specular,
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
        import dataclasses

        return [
            f.name
            for f in dataclasses.fields(self._params)
            if not isinstance(getattr(self._params, f.name), str)
        ]

    def _at(self, part, active):
        """The parameter container with each field gathered for the lanes' parts."""
        import dataclasses

        import drjit as dr

        changes = {}
        for name in self._field_names():
            table = getattr(self._params, name)
            changes[name] = dr.gather(type(table), table, part, active)
        return dataclasses.replace(self._params, **changes)

    # --- what the integrator calls ------------------------------------------------------
    def eval(self, part, wi, wo, active):
        """f_r(wi, wo) in sr^-1 per channel (Color3f)."""
        return self._functions[0](wi, wo, self._at(part, active))

    def eval_specular(self, part, wi, wo, active):
        """The specular (non-diffuse) part of f_r, sr^-1 per channel (Color3f)."""
        return self._functions[1](wi, wo, self._at(part, active))

    def sample(self, part, wo, u_lobe, u2, active):
        """A light direction wi for viewer direction wo, and its pdf (solid angle)."""
        return self._functions[2](wo, u_lobe, u2, self._at(part, active))

    def diffuse_coefficient(self, part, active):
        """kd_eq (Color3f): the diffuse part is about kd_eq / pi cos^c(theta_i)."""
        kd, _ = self._functions[3](self._at(part, active))
        return kd

    def diffuse_band_factors(self, l_max: int) -> np.ndarray:
        """(parts, l_max + 1) Funk-Hecke factors of each part's diffuse kernel cos^(1+c)+.

        The unshadowed diffuse radiance is kd_eq / pi * sum_lm factor_l L_lm Y_lm(n): for a
        Lambertian part the factors are the clamped-cosine A_l (irradiance), for the
        improved Phong diffuse term cos^c(theta_i) those of max(cos, 0)^(1 + c).
        """
        exponents = [
            m.diffuse_exponent_c if self.model == "improved_phong" else 0.0 for m in self.materials
        ]
        rows = {}
        for c in set(exponents):
            if c == 0.0:
                rows[c] = sh.clamped_cosine_coeffs(l_max)
            else:
                power = 1.0 + c
                rows[c] = sh.zonal_kernel_coeffs(lambda t, p=power: np.maximum(t, 0.0) ** p, l_max)
        return np.array([rows[c] for c in exponents])
