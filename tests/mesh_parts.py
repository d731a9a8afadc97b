"""One part of a target mesh as a trimesh of its own, for the mesh tests."""

from __future__ import annotations

import numpy as np
import trimesh

from satsight.scene.mesh import TargetMesh


def part(mesh: TargetMesh, name: str) -> trimesh.Trimesh:
    """Part ``name`` of ``mesh`` as its own trimesh (unreferenced vertices dropped), body
    frame, metres."""
    index = mesh.part_names.index(name)
    faces = mesh.faces[mesh.face_part_index == index]
    used, local = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(mesh.vertices_m[used], local.reshape(-1, 3), process=False)
