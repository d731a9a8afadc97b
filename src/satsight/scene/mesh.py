"""The target as the renderer sees it: one triangle mesh in the body frame, split in parts.

Every triangle belongs to exactly one part; every part has a name and a material. In
masks and labels a part is identified by ``part_id = index + 1`` (0 is background).

Optionally the mesh carries per-corner shading normals (``corner_normals``, see
``satsight.scene.normals``), per-corner texture coordinates (``corner_uv``) and per-part
textures (``part_textures``, see ``satsight.scene.textures``). Without them triangles are
shaded flat and untextured, with the material's values.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from satsight.errors import SatsightError
from satsight.scene.materials import FIRST_MATERIALS, Material
from satsight.scene.normals import crease_normals, face_normals, is_flat, unit_rows
from satsight.scene.textures import SurfaceTextures


@dataclass(frozen=True)
class TargetMesh:
    """A triangulated target in its body frame.

    vertices_m: (N, 3) float64 positions in the body (mesh) frame, metres.
    faces: (M, 3) int64 vertex indices, counter-clockwise seen from outside.
    face_part_index: (M,) int32 index into ``part_names`` for each triangle.
    part_names: one name per part. part_materials: the material name of each part.
    materials: material definitions, by name (at least those the parts use).
    corner_normals: None (flat shading) or (M, 3, 3) float64 unit shading normals at the
    three corners of each triangle, body frame. corner_uv: None or (M, 3, 2) float64
    texture coordinates (u, v) at the corners (u right, v up). part_textures: empty, or
    one ``SurfaceTextures`` or None per part (textures need ``corner_uv``).
    """

    vertices_m: np.ndarray
    faces: np.ndarray
    face_part_index: np.ndarray
    part_names: tuple[str, ...]
    part_materials: tuple[str, ...]
    materials: Mapping[str, Material] = field(default_factory=lambda: dict(FIRST_MATERIALS))
    name: str = "target"
    corner_normals: np.ndarray | None = None
    corner_uv: np.ndarray | None = None
    part_textures: tuple[SurfaceTextures | None, ...] = ()

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices_m, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        p = np.ascontiguousarray(self.face_part_index, dtype=np.int32)
        object.__setattr__(self, "vertices_m", v)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "face_part_index", p)
        object.__setattr__(self, "part_names", tuple(self.part_names))
        object.__setattr__(self, "part_materials", tuple(self.part_materials))
        for key, width in (("corner_normals", 3), ("corner_uv", 2)):
            value = getattr(self, key)
            if value is not None:
                value = np.ascontiguousarray(value, dtype=np.float64)
                if value.shape != (len(f), 3, width) or not np.all(np.isfinite(value)):
                    raise SatsightError(
                        f"mesh '{self.name}': {key} must be finite, of shape "
                        f"({len(f)}, 3, {width}) (one per triangle corner), got {value.shape}"
                    )
                object.__setattr__(self, key, value)
        textures = tuple(self.part_textures)
        if all(t is None or t.empty for t in textures):
            textures = ()
        object.__setattr__(self, "part_textures", textures)
        self._validate()

    def _validate(self) -> None:
        v, f, p = self.vertices_m, self.faces, self.face_part_index
        where = f"mesh '{self.name}'"
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            raise SatsightError(f"{where} has no vertices (expected an (N, 3) array)")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise SatsightError(f"{where} has no triangles; nothing to render")
        if not np.all(np.isfinite(v)):
            raise SatsightError(f"{where} has non-finite vertex positions")
        if f.min() < 0 or f.max() >= len(v):
            raise SatsightError(f"{where} has face indices outside 0..{len(v) - 1}")
        if p.shape != (len(f),):
            raise SatsightError(f"{where}: face_part_index must have one entry per triangle")
        if len(self.part_names) != len(self.part_materials):
            raise SatsightError(f"{where}: one material name is needed per part")
        if len(self.part_names) == 0 or p.min() < 0 or p.max() >= len(self.part_names):
            raise SatsightError(f"{where}: triangles refer to parts that do not exist")
        missing = sorted(set(self.part_materials) - set(self.materials))
        if missing:
            raise SatsightError(
                f"{where}: parts use materials with no definition: {', '.join(missing)}"
            )
        e1 = v[f[:, 1]] - v[f[:, 0]]
        e2 = v[f[:, 2]] - v[f[:, 0]]
        if not np.any(np.linalg.norm(np.cross(e1, e2), axis=1) > 0):
            raise SatsightError(f"{where}: every triangle is degenerate (zero area)")
        if self.part_textures:
            if len(self.part_textures) != len(self.part_names):
                raise SatsightError(f"{where}: part_textures needs one entry (or None) per part")
            if self.corner_uv is None:
                raise SatsightError(f"{where}: textured parts need texture coordinates (corner_uv)")

    @property
    def smooth(self) -> bool:
        """Whether the mesh has shading normals (else triangles are shaded flat)."""
        return self.corner_normals is not None

    @property
    def textured(self) -> bool:
        return bool(self.part_textures)

    def part_texture(self, part_index: int) -> SurfaceTextures | None:
        return self.part_textures[part_index] if self.part_textures else None

    # --- geometry ------------------------------------------------------------------------
    # The box and the bounding sphere are computed once per mesh (a frame asks for them
    # several times: 2 s a frame at 4 M triangles when they were recomputed each time) and
    # handed out read-only. The mesh is frozen, and its arrays are not changed in place.
    @functools.cached_property
    def bounds_m(self) -> np.ndarray:
        """Axis-aligned bounding box in the body frame, (2, 3): [min, max] (read-only)."""
        bounds = np.stack([self.vertices_m.min(axis=0), self.vertices_m.max(axis=0)])
        bounds.setflags(write=False)
        return bounds

    @property
    def center_m(self) -> np.ndarray:
        """Centre of the axis-aligned bounding box, body frame (3,)."""
        return self.bounds_m.mean(axis=0)

    @property
    def extent_m(self) -> np.ndarray:
        """Side lengths of the bounding box (3,)."""
        b = self.bounds_m
        return b[1] - b[0]

    @functools.cached_property
    def bounding_radius_m(self) -> float:
        """Radius of the sphere about ``center_m`` that holds every vertex."""
        return float(np.linalg.norm(self.vertices_m - self.center_m, axis=1).max())

    @property
    def box_keypoints_body_m(self) -> np.ndarray:
        """The 8 bounding-box corners then the box centre, (9, 3), body frame.

        Corner k has x from bit 0, y from bit 1, z from bit 2 of k (0: min, 1: max).
        """
        b = self.bounds_m
        corners = np.array(
            [[b[(k >> 0) & 1, 0], b[(k >> 1) & 1, 1], b[(k >> 2) & 1, 2]] for k in range(8)]
        )
        return np.vstack([corners, self.center_m])

    @property
    def part_ids(self) -> np.ndarray:
        """Per-triangle part id as written in masks: part index + 1 (0 is background)."""
        return self.face_part_index.astype(np.int32) + 1

    def part_material(self, part_index: int) -> Material:
        return self.materials[self.part_materials[part_index]]

    def summary(self) -> dict:
        """Parts, materials and counts, for manifests and labels."""
        counts = np.bincount(self.face_part_index, minlength=len(self.part_names))
        return {
            "name": self.name,
            "vertex_count": len(self.vertices_m),
            "triangle_count": len(self.faces),
            "bounds_m": self.bounds_m.tolist(),
            "parts": [
                {"part_id": i + 1, "name": n, "material": m, "triangle_count": int(c)}
                for i, (n, m, c) in enumerate(
                    zip(self.part_names, self.part_materials, counts, strict=True)
                )
            ],
        }


@dataclass(frozen=True, eq=False)
class PartSurface:
    """Optional surface data of one part for ``merge_parts``.

    vertex_normals: (N, 3) shading normals at the part's vertices, or corner_normals
    (F, 3, 3) at its triangle corners (not both). vertex_uv (N, 2) or corner_uv (F, 3, 2):
    texture coordinates. textures: the part's textures.
    """

    vertex_normals: np.ndarray | None = None
    corner_normals: np.ndarray | None = None
    vertex_uv: np.ndarray | None = None
    corner_uv: np.ndarray | None = None
    textures: SurfaceTextures | None = None

    def normals_at_corners(self, faces: np.ndarray) -> np.ndarray | None:
        if self.corner_normals is not None:
            return np.asarray(self.corner_normals, dtype=np.float64)
        if self.vertex_normals is not None:
            return np.asarray(self.vertex_normals, dtype=np.float64)[faces]
        return None

    def uv_at_corners(self, faces: np.ndarray) -> np.ndarray | None:
        if self.corner_uv is not None:
            return np.asarray(self.corner_uv, dtype=np.float64)
        if self.vertex_uv is not None:
            return np.asarray(self.vertex_uv, dtype=np.float64)[faces]
        return None


def merge_parts(
    parts: Sequence[tuple],
    materials: Mapping[str, Material] | None = None,
    name: str = "target",
    crease_angle_deg: float | None = None,
) -> TargetMesh:
    """Build a TargetMesh from (part_name, material_name, vertices_m (N,3), faces (M,3)) or
    (..., faces, PartSurface) tuples.

    Parts with the same name are kept as separate parts; give unique names for unique ids.
    crease_angle_deg: parts without their own normals get crease-angle shading normals
    (``satsight.scene.normals.crease_normals``); None keeps them flat. Normals never blend
    across parts. The mesh keeps ``corner_normals`` only where some part is not flat.
    """
    if not parts:
        raise SatsightError(f"mesh '{name}' has no parts")
    verts, faces, index, normals, uvs, textures = [], [], [], [], [], []
    offset = 0
    for k, part in enumerate(parts):
        v = np.asarray(part[2], dtype=np.float64)
        f = np.asarray(part[3], dtype=np.int64)
        surface = part[4] if len(part) > 4 and part[4] is not None else PartSurface()
        verts.append(v)
        faces.append(f + offset)
        index.append(np.full(len(f), k, dtype=np.int32))
        offset += len(v)
        flat = np.repeat(face_normals(v, f)[:, None, :], 3, axis=1) if len(f) else None
        n = surface.normals_at_corners(f)
        if n is not None and len(f):
            n = unit_rows(n, flat)
        elif crease_angle_deg is not None and len(f):
            n = crease_normals(v, f, crease_angle_deg)
        if n is not None and len(f) and is_flat(n, v, f):
            n = None
        normals.append((n, flat))
        uvs.append(surface.uv_at_corners(f))
        textures.append(surface.textures)
    corner_normals = None
    if any(n is not None for n, _ in normals):
        corner_normals = np.concatenate(
            [n if n is not None else flat for n, flat in normals if flat is not None]
        )
    textured = any(t is not None and not t.empty for t in textures)
    corner_uv = None
    if textured or any(uv is not None for uv in uvs):
        corner_uv = np.concatenate(
            [
                uv if uv is not None else np.zeros((len(f), 3, 2))
                for uv, f in zip(uvs, faces, strict=True)
            ]
        )
    return TargetMesh(
        vertices_m=np.concatenate(verts),
        faces=np.concatenate(faces),
        face_part_index=np.concatenate(index),
        part_names=tuple(p[0] for p in parts),
        part_materials=tuple(p[1] for p in parts),
        materials=dict(FIRST_MATERIALS if materials is None else materials),
        name=name,
        corner_normals=corner_normals,
        corner_uv=corner_uv,
        part_textures=tuple(textures) if textured else (),
    )
