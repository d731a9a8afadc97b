"""The environment light in the renderer: the light field's SH expansion of radiance.

``EnvironmentLight`` picks the SH coefficients the renderer treats as environment, evaluates
the radiance they give along a direction (clamped at 0: a truncated expansion rings below
zero away from bright sources) and, for ``environment="unshadowed"``, the diffuse radiance
an unshadowed surface reflects (the SH convolution with each part's diffuse kernel).
"""

from __future__ import annotations

import math

import numpy as np

from satsight.lighting import sh
from satsight.lighting.light_field import LightField
from satsight.render.settings import RenderSettings
from satsight.render.surface import SurfaceModel
from satsight.render.target_geometry import TargetGeometry


class EnvironmentLight:
    """The SH environment of one renderer.

    settings: the renderer's settings (``sh_order``, ``environment``, ``sun``). geometry:
    the target's triangles (for the per-face-side diffuse table). surface: the parts'
    reflection models at the first vertex (their diffuse kernels' band factors).
    """

    def __init__(
        self, settings: RenderSettings, geometry: TargetGeometry, surface: SurfaceModel
    ) -> None:
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.settings = settings
        self._geometry = geometry
        # Diffuse environment kernel per part and SH band (see SurfaceModel.diffuse_kernel).
        self.l_max = settings.sh_order
        kernel = surface.diffuse_band_factors(self.l_max)  # (parts, l_max + 1)
        self._band_factors = mi.Float(np.asarray(kernel, dtype=np.float32).ravel())
        dr.eval(self._band_factors)

    def coefficients(self, light: LightField) -> np.ndarray:
        """(n, 3) SH coefficients of the radiance the renderer treats as environment."""
        n = sh.sh_count(self.l_max)
        coeffs = np.zeros((n, 3))
        if self.settings.environment != "off" or self.settings.sun == "sh":
            m = min(n, light.sh_radiance_w_m2_sr.shape[0])
            bodies_traced = self.settings.environment == "sampled" and light.bodies
            if self.settings.environment != "off" and not bodies_traced:
                coeffs[:m] = light.sh_radiance_w_m2_sr[:m]
            if self.settings.sun == "sh":
                sun = sh.delta_coeffs(light.sun_direction_body, self.l_max)
                coeffs += light.sun_irradiance_w_m2 * sun[:, None]
        return coeffs

    def radiance(self, env: tuple, direction):
        """L_env along ``direction`` (towards the source) from the SH coefficients ``env``
        (Color3f each, W m^-2 sr^-1), clamped at 0: a truncated expansion rings below zero
        away from bright sources."""
        basis = sh.sh_eval_dr(direction, self.l_max)
        total = self._mi.Color3f(0.0)
        for k, y in enumerate(basis):
            total += env[k] * y
        return self._dr.maximum(total, 0.0)

    def diffuse_table(self, env: tuple):
        """Per face side, the unshadowed environment's diffuse radiance over kd_eq,
        1 / pi * sum_l k_l E_l(n) (Color3f, W m^-2 sr^-1): entry ``face`` for the side of
        the stored normal, ``face + faces`` for the other (see ``TargetGeometry.face_side``).

        Normals are flat per face, so this one small kernel per frame replaces the SH
        evaluation at every shaded lane by a gather. None where the mesh has shading
        normals: the sum is then evaluated at each hit's shading normal.
        """
        mi, dr = self._mi, self._dr
        if self._geometry.shading_normals:
            return None
        faces = dr.width(self._geometry.face_part)
        side = dr.arange(mi.UInt32, 2 * faces)
        face = side % faces
        n = dr.gather(mi.Vector3f, self._geometry.face_n, face)
        n = dr.select(side < faces, n, -n)
        table = self.diffuse(env, n, dr.gather(mi.UInt32, self._geometry.face_part, face))
        dr.eval(table)
        return table

    def diffuse(self, env: tuple, n, part):
        """Diffuse radiance over kd_eq from the unshadowed environment at unit normal n:
        1 / pi * sum_l k_l E_l(n), with the part's band factors k_l, clamped at 0."""
        mi, dr = self._mi, self._dr
        basis = sh.sh_eval_dr(n, self.l_max)
        total = mi.Color3f(0.0)
        bands = self.l_max + 1
        for l in range(bands):
            band = mi.Color3f(0.0)
            for m in range(-l, l + 1):
                k = l * (l + 1) + m
                band += env[k] * basis[k]
            factor = dr.gather(mi.Float, self._band_factors, part * bands + l)
            total += factor * band
        # Clamped at 0 like the radiance: the truncated expansion can ring below zero.
        return (1.0 / math.pi) * dr.maximum(total, 0.0)
