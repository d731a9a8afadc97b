"""Closed, outward-facing triangle-mesh primitives and the part list satellites are built of.

Used by the procedural satellites (``satsight.scene.procedural``) and the replicas of real
spacecraft (``satsight.scene.replicas``). Every primitive is a closed, watertight solid
whose triangles wind counter-clockwise seen from outside; lengths are metres, rotations
proper (3, 3) matrices, poses 4x4 homogeneous transforms.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import trimesh

from satsight.scene import procedural_textures as pt
from satsight.scene.materials import FIRST_MATERIALS, Material
from satsight.scene.mesh import PartSurface
from satsight.scene.normals import box_uv


def pose(rotation: np.ndarray | None = None, translation_m=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 homogeneous transform: a proper rotation (3, 3) then a translation (3,)."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    T[:3, 3] = translation_m
    return T


def rot(axis: str, angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) by ``angle_rad`` about the body axis 'x', 'y' or 'z'."""
    vec = {"x": [1.0, 0, 0], "y": [0, 1.0, 0], "z": [0, 0, 1.0]}[axis]
    return trimesh.transformations.rotation_matrix(angle_rad, vec)[:3, :3]


def box(extents_m, center_m, rotation: np.ndarray | None = None) -> trimesh.Trimesh:
    """Closed box with side lengths ``extents_m`` (3,), centred at ``center_m`` (3,)."""
    return trimesh.creation.box(extents=extents_m, transform=pose(rotation, center_m))


def rod(start_m, end_m, radius_m: float, sections: int = 24) -> trimesh.Trimesh:
    """Closed cylinder of ``radius_m`` whose axis runs from ``start_m`` to ``end_m``."""
    return trimesh.creation.cylinder(
        radius=radius_m, segment=np.array([start_m, end_m], dtype=float), sections=sections
    )


def tube(r_in_m: float, r_out_m: float, z0_m: float, z1_m: float, xy_m) -> trimesh.Trimesh:
    """Closed thick-walled tube about a +z axis through ``xy_m``, from z0 to z1."""
    centre = (xy_m[0], xy_m[1], 0.5 * (z0_m + z1_m))
    return trimesh.creation.annulus(
        r_min=r_in_m, r_max=r_out_m, height=z1_m - z0_m, sections=48, transform=pose(None, centre)
    )


def dish(diameter_m: float, focal_m: float, thickness_m: float, sections: int) -> trimesh.Trimesh:
    """Paraboloid shell z = r^2 / (4 f), axis +z, vertex at the origin, concave side at +z.

    The shell is ``thickness_m`` thick below the reflecting surface; it is a closed solid of
    revolution of the (r, z) profile back surface -> rim -> front surface.
    """
    r = np.linspace(0.0, 0.5 * diameter_m, 14)
    z = r**2 / (4.0 * focal_m)
    back = np.column_stack([r, z - thickness_m])
    front = np.column_stack([r[::-1], z[::-1]])
    mesh = trimesh.creation.revolve(np.vstack([back, front]), sections=sections)
    if mesh.volume < 0:  # keep normals outward whatever the profile orientation
        mesh.invert()
    return mesh


def join(*meshes: trimesh.Trimesh) -> trimesh.Trimesh:
    """One part made of several closed components (not merged, not booleaned)."""
    return trimesh.util.concatenate(list(meshes))


class Parts:
    """Ordered (name, material, vertices_m, faces, PartSurface | None) parts with unique
    names; ``textures`` (a generator, or None) switches the parts' textures on."""

    def __init__(
        self,
        textures: np.random.Generator | None = None,
        materials: Mapping[str, Material] = FIRST_MATERIALS,
    ) -> None:
        self.items: list[tuple] = []
        self.texture_rng = textures
        self.materials = materials
        self._cells: dict[tuple[float, float], pt.SurfaceTextures] = {}

    def add(
        self, name: str, material: str, mesh: trimesh.Trimesh, surface: PartSurface | None = None
    ) -> None:
        if any(name == item[0] for item in self.items) or material not in self.materials:
            raise ValueError(f"internal: duplicate part '{name}' or bad material '{material}'")
        if self.texture_rng is None:
            surface = None
        self.items.append(
            (name, material, np.array(mesh.vertices, dtype=float), np.array(mesh.faces), surface)
        )

    def cell_textures(self, pitch_uv_m: tuple[float, float]) -> pt.SurfaceTextures:
        """The cell tile of this pitch (made once, shared by the panels that use it)."""
        key = (round(pitch_uv_m[0], 9), round(pitch_uv_m[1], 9))
        if key not in self._cells:
            self._cells[key] = pt.solar_cell_textures(pitch_uv_m, self.materials)
        return self._cells[key]


def textured(
    mesh: trimesh.Trimesh, textures, size_uv_m, origin_m, axes=None, pose=None
) -> tuple[trimesh.Trimesh, PartSurface]:
    """``mesh`` (moved by ``pose``) with planar texture coordinates taken in its own frame
    (``satsight.scene.normals.box_uv``) and ``textures``."""
    uv = box_uv(mesh.vertices, mesh.faces, size_uv_m, origin_m, axes)
    if pose is not None:
        if np.linalg.det(pose[:3, :3]) <= 0:  # a mirror would reorder the corners
            raise ValueError("internal: textured parts take proper rotations only")
        mesh = mesh.apply_transform(pose)
    return mesh, PartSurface(corner_uv=uv, textures=textures)


def cell_surface(parts: Parts, mesh, extent_uv_m, origin_m, axes=None, pose=None):
    """Solar cells of a panel whose cell area spans ``extent_uv_m`` along (u, v): a whole
    number of cells (the busbar along u) fills it."""
    pitch = (
        pt.cell_pitch_m(extent_uv_m[0], pt.CELL_SIZE_M[0]),
        pt.cell_pitch_m(extent_uv_m[1], pt.CELL_SIZE_M[1]),
    )
    if parts.texture_rng is None:
        return (mesh if pose is None else mesh.apply_transform(pose)), None
    return textured(mesh, parts.cell_textures(pitch), pitch, origin_m, axes, pose)
