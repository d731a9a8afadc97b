"""The target's sunlit surfaces as light sources of inter-reflection (next-event
estimation of reflected sunlight).

A path vertex in the shade of a sunlit wing gets the wing's light through its bounce ray
only when that ray happens to meet the lit part: at one path per pixel some pixels pick it
up and their neighbours do not, which shows as isolated bright pixels (on/off noise) on
the dark parts. So each vertex that continues its path also picks a point q on the
target's triangles, with probability proportional to

    area x reflectance of its part x |cos(sun, face normal)|

(the Sun's power the face reflects; ``frame_tables``), tests whether q is seen from the
vertex, and adds the Sun's light q reflects towards it. The bounce ray's own way to that
light (the Sun at the next vertex) and this one are combined by multiple importance
sampling (power heuristic), with the density of q in solid angle seen from the vertex,
pdf_area(q) r^2 / |cos theta_q|. Both estimate the same integral, so the result's mean
does not change; the variance of the light reflected by lit parts onto shaded ones drops
(benchmarks/firefly_check.py). The weights only shape the efficiency: a face of weight 0
is reached by the bounce ray alone, with full weight.

The face choice inverts the frame's cumulative table by binary search (Dr.Jit), the point
is uniform on the triangle; the tables are per-frame arrays of the kernels, so frames
reuse the compiled code.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from satsight.constants import REC709_LUMINANCE_RGB
from satsight.scene.materials import Material

#: The face choice's uniform numbers are multiples of 1 / _U_STEPS (PCG32 next_float32).
_U_STEPS = float(2**23)
_LUMINANCE_RGB = np.array(REC709_LUMINANCE_RGB)


def part_reflectance(material: Material) -> float:
    """A part's hemispherical reflectance at normal incidence, roughly: the luminance of its
    base colour plus the dielectric Fresnel reflectance of its non-metallic share. Only
    the sampling weights use it."""
    base = float(np.dot(_LUMINANCE_RGB, material.base_color_rgb))
    f0 = ((material.ior - 1.0) / (material.ior + 1.0)) ** 2
    return min(1.0, base + (1.0 - material.metallic) * f0)


@dataclass(frozen=True, eq=False)
class SunlitTables:
    """One frame's sampling tables (Dr.Jit Float arrays, one entry per triangle).

    cdf: the cumulative probability of the faces (last entry 1). pdf_area_per_m2: the
    density of a point on each face per unit area, m^-2 (its probability over its area).
    """

    cdf: object
    pdf_area_per_m2: object


class SunlitSurfaces:
    """The triangles of a target as light sources of reflected sunlight.

    face_area_m2: (faces,) areas. face_normal: (faces, 3) unit normals, body frame.
    face_part: (faces,) part indices. materials: one per part.
    """

    def __init__(
        self,
        face_area_m2: np.ndarray,
        face_normal: np.ndarray,
        face_part: np.ndarray,
        materials: Sequence[Material],
    ) -> None:
        reflectance = np.array([part_reflectance(m) for m in materials], dtype=np.float64)
        self._area_m2 = np.asarray(face_area_m2, dtype=np.float64)
        self._normal = np.asarray(face_normal, dtype=np.float64)
        self._power_per_irradiance = self._area_m2 * reflectance[np.asarray(face_part)]

    def face_weights(self, sun_direction_body: np.ndarray) -> np.ndarray:
        """(faces,) float64: the sunlight each face reflects per unit irradiance, m^2."""
        cosine = np.abs(self._normal @ np.asarray(sun_direction_body, dtype=np.float64))
        return self._power_per_irradiance * cosine

    def frame_tables(self, sun_direction_body: np.ndarray) -> SunlitTables | None:
        """The frame's tables for a Sun in ``sun_direction_body`` (unit, body frame), or
        None where no face reflects sunlight.

        The face probabilities are those the kernels' search really gives: a face is
        drawn where the uniform number u < its cumulative value, and u (PCG32
        ``next_float32``) is a multiple of 2^-23, so face i is drawn with probability
        (ceil(cdf_i 2^23) - ceil(cdf_(i-1) 2^23)) / 2^23, exactly; a face of 1e-6 of the
        weight on a million-face mesh is off by up to 10 % otherwise."""
        import mitsuba as mi

        weights = self.face_weights(sun_direction_body)
        total = float(weights.sum())
        if not total > 0.0:
            return None
        cdf = (np.cumsum(weights) / total).astype(np.float32)
        cdf[-1] = 1.0
        grid = np.ceil(cdf.astype(np.float64) * _U_STEPS)
        pmf = np.diff(grid, prepend=0.0) / _U_STEPS
        area = self._area_m2
        pdf_area = np.divide(pmf, area, out=np.zeros_like(pmf), where=area > 0.0)
        return SunlitTables(mi.Float(cdf), mi.Float(pdf_area.astype(np.float32)))

    @staticmethod
    def sample(tables: SunlitTables, u_face, u1, u2):
        """A point on the target: (face UInt32, barycentrics u, v of point = v0 + u e1 +
        v e2, its density per unit area pdf_area, m^-2), from three uniform numbers."""
        import drjit as dr
        import mitsuba as mi

        cdf = tables.cdf
        last = dr.width(cdf) - 1
        face = dr.binary_search(0, last, lambda i: dr.gather(mi.Float, cdf, i) <= u_face)
        face = dr.minimum(mi.UInt32(face), last)
        root = dr.sqrt(u1)  # uniform on the triangle
        return face, root * (1.0 - u2), root * u2, SunlitSurfaces.pdf_area(tables, face, True)

    @staticmethod
    def pdf_area(tables: SunlitTables, face, active):
        """The density per unit area with which ``sample`` picks a point of ``face``, m^-2."""
        import drjit as dr
        import mitsuba as mi

        return dr.gather(mi.Float, tables.pdf_area_per_m2, face, active)
