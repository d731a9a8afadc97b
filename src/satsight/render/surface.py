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
from typing import TYPE_CHECKING

import numpy as np

from satsight.lighting import sh
from satsight.render import ggx, phong
from satsight.render.settings import RenderSettings
from satsight.render.textures import TextureTables, guarded
from satsight.scene.materials import Material

if TYPE_CHECKING:
    from satsight.render.path_records import PathVertex


@dataclasses.dataclass(frozen=True)
class SurfaceHit:
    """The model's parameters at a hit, the geometric normal in the shading frame (None
    where it equals the shading normal) and the smooth surface's normal there (the
    interpolated corner normal, the horizon of light sources; None where it is the
    geometric normal)."""

    params: object
    n_geo_local: object = None
    n_smooth_local: object = None


def _phong_tables(materials: Sequence[Material]) -> dict[str, np.ndarray]:
    """The Phong models' coefficients per part (``Material.phong_coefficients``)."""
    coefficients = [m.phong_coefficients for m in materials]
    return {
        "kd": np.array([p.kd_rgb for p in coefficients]),
        "ks": np.array([p.ks_rgb for p in coefficients]),
        "g": np.array([p.gloss_exponent_g for p in coefficients]),
        "a": np.array([p.fresnel_exponent_a for p in coefficients]),
        "b": np.array([p.lobe_decay_b for p in coefficients]),
        "c": np.array([p.diffuse_exponent_c for p in coefficients]),
    }


def regularized(material: Material, min_roughness: float) -> Material:
    """The material with its roughness raised to ``min_roughness`` (and an explicit Phong
    gloss exponent capped at the matching value); unchanged when already rougher."""
    if material.roughness >= min_roughness:
        return material
    rougher = dataclasses.replace(material, roughness=min_roughness, gloss_exponent_g=None)
    cap = rougher.phong_gloss_exponent
    if material.gloss_exponent_g is not None:
        rougher = dataclasses.replace(rougher, gloss_exponent_g=min(material.gloss_exponent_g, cap))
    if material.phong is not None:
        capped = min(material.phong.gloss_exponent_g, cap)
        rougher = dataclasses.replace(
            rougher, phong=dataclasses.replace(material.phong, gloss_exponent_g=capped)
        )
    return rougher


class SurfaceModel:
    """The reflection model of every part of a target.

    materials: one per part, in part-index order. settings: the model (``brdf``) and, for
    GGX, its masking term. textures: the target's textures, or None. min_roughness: floor
    of textured roughness (the path regularisation of surfaces reached by a bounce).
    shading_normals: whether shading normals may differ from geometric ones (then ``at``
    keeps the geometric normal of the hit).
    """

    def __init__(
        self,
        materials: Sequence[Material],
        settings: RenderSettings,
        textures: TextureTables | None = None,
        min_roughness: float = 0.0,
        shading_normals: bool = False,
    ) -> None:
        import mitsuba as mi

        self._mi = mi
        self.model = settings.brdf
        self.materials = list(materials)
        self.textures = textures
        self.min_roughness = float(min_roughness)
        self.shading_normals = shading_normals
        self._textured = textures is not None and (
            textures.has_slot["base_color"] or textures.has_slot["metallic_roughness"]
        )
        self._factors = None
        if self._textured and self.model != "ggx":
            # The material values the Phong coefficients are computed from, and for parts
            # with explicit coefficients their offsets from the mapped ones (a textured
            # texel gets the mapped coefficients of its values plus these offsets).
            base = np.array([m.base_color_rgb for m in materials], dtype=np.float32)
            explicit = [m.phong is not None for m in materials]
            offset_kd = np.array(
                [np.subtract(m.phong_coefficients.kd_rgb, m.phong_kd_rgb) for m in materials]
            )
            offset_ks = np.array(
                [np.subtract(m.phong_coefficients.ks_rgb, m.ks_rgb) for m in materials]
            )
            self._factors = {
                "base": mi.Color3f(base.T),
                "metallic": mi.Float(np.array([m.metallic for m in materials], np.float32)),
                "f0": mi.Float(np.array([m.f0 for m in materials], np.float32)),
                "explicit": mi.Bool(np.array(explicit, dtype=bool)),
                "offset_kd": mi.Color3f(offset_kd.astype(np.float32).T),
                "offset_ks": mi.Color3f(offset_ks.astype(np.float32).T),
            }
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
                t["kd"], t["ks"], t["g"], t["a"], t["b"], t["c"]
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
        dr.eval(*fields, *(self._factors or {}).values())

    def _field_names(self) -> list[str]:
        return [
            f.name
            for f in dataclasses.fields(self._params)
            if not isinstance(getattr(self._params, f.name), str)
        ]

    def at(self, part, active, hit: PathVertex | None = None, frame=None):
        """The model's parameters at the lanes' hits (``SurfaceHit``): each part's values,
        textured at ``hit.uv`` (with mip level ``hit.mip_level`` where given), and the
        geometric normal ``hit.normal_geo`` in the shading ``frame`` (mi.Frame3f). Gather
        once per surface hit and pass the result to the calls below."""
        import drjit as dr

        changes = {}
        for name in self._field_names():
            table = getattr(self._params, name)
            changes[name] = dr.gather(type(table), table, part, active)
        if self._textured and hit is not None:
            self._apply_textures(changes, part, active, hit)
        params = dataclasses.replace(self._params, **changes)
        n_geo_local = n_smooth_local = None
        if self.shading_normals and hit is not None and frame is not None:
            n_geo_local = frame.to_local(hit.normal_geo)
            if hit.normal_smooth is not None:
                n_smooth_local = frame.to_local(hit.normal_smooth)
        return SurfaceHit(params, n_geo_local, n_smooth_local)

    def _apply_textures(self, values: dict, part, active, hit: PathVertex) -> None:
        """Replace the gathered values by their textured ones where a part has textures."""
        import drjit as dr

        mi, tex = self._mi, self.textures
        uv, lod = hit.uv, hit.mip_level
        replace = tex.replaces(part, active)
        if self.model == "ggx":
            base, metallic, roughness = values["base"], values["metallic"], values["roughness"]
        else:
            f = self._factors
            base = dr.gather(mi.Color3f, f["base"], part, active)
            metallic = dr.gather(mi.Float, f["metallic"], part, active)
        textured = mi.Bool(False)

        def lookup(slot: str, srgb: bool):
            """(the slot's filtered value, where the lane's part has that texture)."""
            texture = tex.slot(slot, part, active)
            has = active & (texture >= 0)
            value = guarded(
                has,
                lambda: tex.sample(texture, uv, has, lod, srgb=srgb),
                lambda: mi.Color3f(1.0),
            )
            return value, has

        if tex.has_slot["base_color"]:
            value, has = lookup("base_color", srgb=True)
            base = dr.select(has, dr.select(replace, value, base * value), base)
            textured |= has
        if tex.has_slot["metallic_roughness"]:
            value, has = lookup("metallic_roughness", srgb=False)  # G roughness, B metallic
            metallic = dr.select(has, dr.select(replace, value.z, metallic * value.z), metallic)
            if self.model == "ggx":
                rough = dr.select(replace, value.y, roughness * value.y)
                roughness = dr.select(has, dr.maximum(rough, self.min_roughness), roughness)
            textured |= has
        if self.model == "ggx":
            values.update(base=base, metallic=metallic, roughness=roughness)
            return
        f0 = dr.gather(mi.Float, self._factors["f0"], part, active)
        kd = (1.0 - metallic) * base * (1.0 - f0)
        ks = metallic * base + (1.0 - metallic) * f0
        # Parts with explicit coefficients: the texel's mapped coefficients moved by the
        # part's offset (explicit - mapped), clamped to reflectances with kd + ks <= 1.
        explicit = dr.gather(mi.Bool, self._factors["explicit"], part, active)
        kd_x = dr.maximum(kd + dr.gather(mi.Color3f, self._factors["offset_kd"], part, active), 0)
        ks_x = dr.maximum(ks + dr.gather(mi.Color3f, self._factors["offset_ks"], part, active), 0)
        excess = dr.maximum(kd_x + ks_x, 1.0)
        kd = dr.select(explicit, kd_x / excess, kd)
        ks = dr.select(explicit, ks_x / excess, ks)
        values["kd"] = dr.select(textured, kd, values["kd"])
        values["ks"] = dr.select(textured, ks, values["ks"])

    # --- what the integrator calls ------------------------------------------------------
    @staticmethod
    def _unwrap(params):
        if isinstance(params, SurfaceHit):
            return params.params, params.n_geo_local
        return params, None

    def eval_parts(self, params, wi, wo, smooth_horizon: bool = False):
        """(diffuse, specular) parts of f_r(wi, wo), sr^-1 per channel (Color3f each); 0
        for light from below the geometric surface.

        smooth_horizon: the horizon is the smooth surface's (``SurfaceHit.n_smooth_local``)
        instead of the triangle's, for light sources whose shadow ray starts on that
        surface (``satsight.render.target_geometry``)."""
        import drjit as dr

        model, n_geo = self._unwrap(params)
        if smooth_horizon and isinstance(params, SurfaceHit) and params.n_smooth_local is not None:
            n_geo = params.n_smooth_local
        f_diffuse, f_specular = self._functions[0](wi, wo, model)
        if n_geo is not None:
            above = dr.dot(wi, n_geo) > 0.0
            f_diffuse = dr.select(above, f_diffuse, 0.0)
            f_specular = dr.select(above, f_specular, 0.0)
        return f_diffuse, f_specular

    def sample(self, params, wo, u_lobe, u2):
        """A light direction wi for viewer direction wo, and its pdf (solid angle); pdf 0
        where wi lies below the geometric surface."""
        import drjit as dr

        model, n_geo = self._unwrap(params)
        wi, pdf = self._functions[1](wo, u_lobe, u2, model)
        if n_geo is not None:
            pdf = dr.select(dr.dot(wi, n_geo) > 0.0, pdf, 0.0)
        return wi, pdf

    def pdf(self, params, wi, wo):
        """Solid-angle density with which ``sample`` picks wi for viewer direction wo (0
        below the geometric surface, where ``sample`` gives pdf 0)."""
        import drjit as dr

        model, n_geo = self._unwrap(params)
        function = {
            "ggx": ggx.ggx_pdf,
            "phong": phong.phong_pdf,
            "improved_phong": phong.improved_phong_pdf,
        }[self.model]
        pdf = function(wi, wo, model)
        if n_geo is not None:
            pdf = dr.select(dr.dot(wi, n_geo) > 0.0, pdf, 0.0)
        return pdf

    def diffuse_coefficient(self, params, wo):
        """kd_eq (Color3f) for viewer direction wo: the diffuse part is kd_eq / pi times the
        part's zonal kernel of theta_i (see ``diffuse_band_factors``) over cos(theta_i)."""
        model, _ = self._unwrap(params)
        if self.model == "ggx":
            kd, _ = ggx.ggx_diffuse_coefficient(model, wo)
        else:
            kd, _ = self._functions[2](model)
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
                keys.append(("power", 1.0 + m.phong_coefficients.diffuse_exponent_c))
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
