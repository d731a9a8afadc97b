"""Small geometry builders shared by tests."""

from __future__ import annotations

import numpy as np


def plate_parts(size_m: float = 2.0, z_m: float = 0.0):
    """A square plate of side size_m in the plane z = z_m, normal +z (two triangles)."""
    h = size_m / 2.0
    vertices = np.array([[-h, -h, z_m], [h, -h, z_m], [h, h, z_m], [-h, h, z_m]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return vertices, faces
