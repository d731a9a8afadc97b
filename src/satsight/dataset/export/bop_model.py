"""The BOP object model: ``models/obj_000001.ply`` and ``models/models_info.json``.

BOP models are ASCII PLY files in millimetres with vertex normals, in the object's model
frame (bop_toolkit docs/bop_datasets_format.md, "3D object models" and "Units"; the
header layout follows bop_toolkit_lib/inout.py ``save_ply2``: ``property float`` x, y, z,
nx, ny, nz and ``property list uchar int vertex_indices``). satsight's model frame is the
target's body frame, unchanged: the mesh is not recentred on its bounding box (as BOP
models are), so that the poses stay those of the satsight labels.

models_info.json holds per object ``diameter`` (largest distance between two vertices),
``min_x``, ``min_y``, ``min_z`` and ``size_x``, ``size_y``, ``size_z`` (the vertices'
axis-aligned box), all in mm (bop_toolkit scripts/calc_model_info.py).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from satsight.scene.mesh import TargetMesh
from satsight.scene.normals import angle_weighted_vertex_normals

MM_PER_M = 1000.0
#: Vertices per block of the pairwise-distance search (memory ~ block^2 * 8 bytes).
_BLOCK = 2048


def ply_text(vertices_mm: np.ndarray, normals: np.ndarray, faces: np.ndarray) -> str:
    """ASCII PLY of a triangle mesh with vertex normals (BOP's model layout)."""
    out = io.StringIO()
    out.write(
        "ply\nformat ascii 1.0\n"
        "comment satsight target model: body frame, millimetres\n"
        f"element vertex {len(vertices_mm)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(faces)}\n"
        "property list uchar int vertex_indices\n"
        "end_header\n"
    )
    np.savetxt(out, np.hstack([vertices_mm, normals]), fmt="%.4f %.4f %.4f %.6f %.6f %.6f")
    np.savetxt(out, np.hstack([np.full((len(faces), 1), 3), faces]), fmt="%d")
    return out.getvalue()


def diameter(points: np.ndarray) -> float:
    """Largest distance between two of the points (exact: searched on the convex hull)."""
    points = np.asarray(points, dtype=np.float64)
    try:
        points = points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        pass  # flat or tiny point sets: search them all
    best = 0.0
    for start in range(0, len(points), _BLOCK):
        block = points[start : start + _BLOCK]
        d2 = ((block[:, None, :] - points[None, start:, :]) ** 2).sum(axis=-1)
        best = max(best, float(d2.max()))
    return float(np.sqrt(best))


def models_info_entry(vertices_mm: np.ndarray) -> dict:
    """One object's models_info.json entry (mm)."""
    low = vertices_mm.min(axis=0)
    size = vertices_mm.max(axis=0) - low
    return {
        "diameter": diameter(vertices_mm),
        "min_x": float(low[0]),
        "min_y": float(low[1]),
        "min_z": float(low[2]),
        "size_x": float(size[0]),
        "size_y": float(size[1]),
        "size_z": float(size[2]),
    }


def write_bop_model(mesh: TargetMesh, models_dir: Path, obj_id: int = 1) -> dict:
    """Write ``obj_{obj_id:06d}.ply`` of the target mesh (metres); its info entry (mm)."""
    vertices_mm = mesh.vertices_m * MM_PER_M
    normals = angle_weighted_vertex_normals(mesh.vertices_m, mesh.faces)
    models_dir.mkdir(parents=True, exist_ok=True)
    text = ply_text(vertices_mm, normals, mesh.faces)
    (models_dir / f"obj_{obj_id:06d}.ply").write_text(text, encoding="ascii")
    return models_info_entry(vertices_mm)
