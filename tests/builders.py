"""Small geometry builders shared by tests."""

from __future__ import annotations

import numpy as np
from scipy import integrate

from satsight.scene.materials import Material
from satsight.scene.mesh import TargetMesh, merge_parts


def plate_parts(size_m: float = 2.0, z_m: float = 0.0):
    """A square plate of side size_m in the plane z = z_m, normal +z (two triangles)."""
    h = size_m / 2.0
    vertices = np.array([[-h, -h, z_m], [h, -h, z_m], [h, h, z_m], [-h, h, z_m]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return vertices, faces


def v_mesh(material_a: Material, material_b: Material) -> TargetMesh:
    """The "V": plate A in z = 0 (x in [0, 2], y in [-1, 1], normal +z), part 1; plate B in
    x = 0 (z in [0, 2], normal +x), part 2."""
    a_vertices = np.array([[0, -1, 0], [2, -1, 0], [2, 1, 0], [0, 1, 0]], dtype=float)
    b_vertices = np.array([[0, -1, 0], [0, 1, 0], [0, 1, 2], [0, -1, 2]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return merge_parts(
        [("a", material_a.name, a_vertices, faces), ("b", material_b.name, b_vertices, faces)],
        {material_a.name: material_a, material_b.name: material_b},
        "v",
    )


def view_integral_to_b(x: float, y: float, z_min: float = 0.0) -> float:
    """Integral over plate B of the V (``v_mesh``), above z = z_min, of cos(theta_x)
    cos(theta_q) / r^2 dA, seen from the point (x, y, 0) of plate A (scipy quadrature)."""

    def integrand(yb, zb):
        r2 = x * x + (yb - y) ** 2 + zb * zb
        return x * zb / (r2 * r2)

    value, _ = integrate.dblquad(integrand, z_min, 2.0, -1.0, 1.0, epsabs=1e-10, epsrel=1e-8)
    return value
