"""Other objects beside the target: debris fragments and placed meshes, merged into one
mesh for the renderer.

The rendered scene is one ``TargetMesh``: the target's parts first, with their ids 1..P
unchanged, then each object's parts in order. ``SceneMesh`` keeps which part ids belong
to which object, so masks and labels can tell them apart: object id 1 is the target, 2..
the objects in the order given.

Objects are placed by a rigid transform fixed in the target's body frame
(``target_from_object``): they move with the target.

Debris sizes follow the NASA standard breakup model's cumulative size distribution for
explosions, N(>Lc) = 6 M^0.75 Lc^-1.6 (Johnson, Krisko, Liou & Anz-Meador, "NASA's new
breakup model of EVOLVE 4.0", Adv. Space Res. 28(9), 1377-1384, 2001, Eq. 2): a power law
whose cumulative exponent is 1.6, here truncated to [L_min, L_max]. The characteristic
length Lc is the mean of a fragment's three extents along its principal axes (ibid., sec.
2). Fragments are seeded convex hulls of points on a flattened ellipsoid, placed uniform in
volume in a spherical shell about the target's box centre, turned uniform at random.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.scene.materials import Material
from satsight.scene.mesh import TargetMesh
from satsight.scene.normals import face_normals

#: Cumulative size exponent of the NASA standard breakup model, explosions (Johnson et al.
#: 2001, Eq. 2: N(>Lc) = 6 M^0.75 Lc^-1.6).
BREAKUP_SIZE_EXPONENT = 1.6
#: The library materials debris fragments are made of (``satsight materials``).
DEBRIS_MATERIALS = ("library:aluminium", "library:mli_aluminised_kapton", "library:cfrp")
#: Points whose hull makes one fragment.
_HULL_POINTS = 14


def sample_breakup_sizes_m(
    count: int, size_m: tuple[float, float], rng: np.random.Generator
) -> np.ndarray:
    """(count,) characteristic lengths (m) drawn from N(>L) proportional to L^-1.6 truncated
    to [L_min, L_max] (inverse transform of its CDF, ``breakup_size_cdf``)."""
    lo, hi = float(size_m[0]), float(size_m[1])
    if not (0 < lo <= hi):
        raise SatsightError(f"debris size_m must satisfy 0 < min <= max, got {list(size_m)}")
    if lo == hi:
        return np.full(count, lo)
    a = BREAKUP_SIZE_EXPONENT
    u = rng.random(count)
    return (lo**-a - u * (lo**-a - hi**-a)) ** (-1.0 / a)


def breakup_size_cdf(size_m: np.ndarray, bounds_m: tuple[float, float]) -> np.ndarray:
    """P(L <= size) of the truncated power law (the oracle of ``sample_breakup_sizes_m``)."""
    lo, hi = bounds_m
    a = BREAKUP_SIZE_EXPONENT
    s = np.clip(np.asarray(size_m, dtype=np.float64), lo, hi)
    return (lo**-a - s**-a) / (lo**-a - hi**-a)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation matrix uniform on SO(3) (a normalised 4D Gaussian quaternion)."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def fragment_hull(size_m: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One irregular fragment centred at the origin: (vertices (N, 3), faces (M, 3)) with
    faces counter-clockwise seen from outside, its mean principal extent equal to size_m.

    The points lie on an ellipsoid of axes 1, [0.3, 1], [0.05, 0.3] (a flattened piece, as
    breakup fragments mostly are plates and shards), jittered radially by up to 20 %.
    """
    from scipy.spatial import ConvexHull

    axes = np.array([1.0, rng.uniform(0.3, 1.0), rng.uniform(0.05, 0.3)])
    d = rng.normal(size=(_HULL_POINTS, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    points = d * axes * rng.uniform(0.8, 1.0, size=(_HULL_POINTS, 1))
    hull = ConvexHull(points)
    v = points[hull.vertices]
    remap = np.full(len(points), -1)
    remap[hull.vertices] = np.arange(len(hull.vertices))
    f = remap[hull.simplices]
    centre = v.mean(axis=0)
    outward = np.einsum("ij,ij->i", face_normals(v, f), v[f].mean(axis=1) - centre) > 0
    f[~outward] = f[~outward][:, ::-1]
    v = v - centre
    extent = v.max(axis=0) - v.min(axis=0)  # axes of the ellipsoid are its principal axes
    v *= size_m / extent.mean()
    return v, f


@dataclass(frozen=True)
class DebrisCloud:
    """Fragments around the target: sizes, centres (target body frame) and the mesh."""

    mesh: TargetMesh
    sizes_m: np.ndarray
    centers_m: np.ndarray


def debris_cloud(
    name: str,
    count: int,
    size_m: tuple[float, float],
    shell_m: tuple[float, float],
    center_m: np.ndarray,
    materials: Mapping[str, Material],
    seed: int,
) -> DebrisCloud:
    """``count`` fragments (module docstring), one part each, in the target's body frame:
    centres uniform in volume with r_min <= |x - center_m| <= r_max. materials: the
    definitions of ``DEBRIS_MATERIALS`` (each fragment takes one at random)."""
    r_min, r_max = float(shell_m[0]), float(shell_m[1])
    if count < 1:
        raise SatsightError(f"debris '{name}': count must be at least 1, got {count}")
    if not (0 <= r_min <= r_max):
        raise SatsightError(f"debris '{name}': shell_m must satisfy 0 <= r_min <= r_max")
    rng = np.random.default_rng(np.random.SeedSequence([seed, count]))
    sizes = sample_breakup_sizes_m(count, size_m, rng)
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radius = (r_min**3 + rng.random(count) * (r_max**3 - r_min**3)) ** (1.0 / 3.0)
    centers = np.asarray(center_m, dtype=np.float64) + direction * radius[:, None]
    parts = []
    for k in range(count):
        v, f = fragment_hull(float(sizes[k]), rng)
        v = v @ _random_rotation(rng).T + centers[k]
        material = DEBRIS_MATERIALS[int(rng.integers(len(DEBRIS_MATERIALS)))]
        parts.append((f"fragment_{k:03d}", material, v, f))
    verts, faces, index, offset = [], [], [], 0
    for k, (_, _, v, f) in enumerate(parts):
        verts.append(v)
        faces.append(f + offset)
        index.append(np.full(len(f), k))
        offset += len(v)
    mesh = TargetMesh(
        np.concatenate(verts),
        np.concatenate(faces),
        np.concatenate(index),
        tuple(p[0] for p in parts),
        tuple(p[1] for p in parts),
        materials=dict(materials),
        name=name,
    )
    return DebrisCloud(mesh, sizes, centers)


@dataclass(frozen=True)
class SceneMesh:
    """The target and the other objects as one mesh for the renderer.

    mesh: the merged mesh (the target's parts 1..P first). object_names: the objects' names
    (object id k + 2 for entry k). part_object_id: (parts + 1,) uint8 object id of each
    part id (0 for background, 1 the target). target_from_object: each object's pose in
    the target's body frame.
    """

    mesh: TargetMesh
    target_part_count: int
    object_names: tuple[str, ...]
    part_object_id: np.ndarray
    target_from_object: tuple[RigidTransform, ...]

    def object_id(self, part_id: np.ndarray) -> np.ndarray:
        """(H, W) uint8 object ids (0 background, 1 target, 2.. objects) of a part-id image."""
        return self.part_object_id[np.asarray(part_id)]


def _corner_normals(mesh: TargetMesh, R: np.ndarray) -> np.ndarray:
    if mesh.corner_normals is not None:
        return mesh.corner_normals @ R.T
    n = face_normals(mesh.vertices_m, mesh.faces) @ R.T
    return np.repeat(n[:, None, :], 3, axis=1)


def merge_scene(
    target: TargetMesh,
    objects: Sequence[tuple[str, TargetMesh, RigidTransform]],
    absent: frozenset[int] = frozenset(),
) -> SceneMesh:
    """The target and ``objects`` (name, mesh in its own frame, target_from_object) as one
    mesh in the target's body frame: vertices moved, normals turned, part indices offset,
    part names prefixed ``name/``; materials pooled (the target's definitions win a name).
    absent: indices into ``objects`` left out of the geometry (their parts keep their ids
    in the part table, so every other part's id and object id stay)."""
    if len(objects) > 253:
        raise SatsightError(f"at most 253 objects fit an 8-bit object-id mask, got {len(objects)}")
    names = [name for name, _, _ in objects]
    if len(set(names)) != len(names) or "target" in names:
        raise SatsightError(f"object names must be unique and not 'target', got {names}")
    meshes = [(target, RigidTransform.identity())] + [(m, pose) for _, m, pose in objects]
    smooth = any(m.smooth for m, _ in meshes)
    textured = any(m.textured for m, _ in meshes)
    with_uv = textured or any(m.corner_uv is not None for m, _ in meshes)
    verts, faces, index, normals, uvs, textures = [], [], [], [], [], []
    part_names, part_materials, owner = [], [], [0]
    materials: dict[str, Material] = {}
    offset = part_offset = 0
    for k, (mesh, pose) in enumerate(meshes):
        parts = len(mesh.part_names)
        if k - 1 not in absent:
            verts.append(pose.apply(mesh.vertices_m))
            faces.append(mesh.faces + offset)
            index.append(mesh.face_part_index + part_offset)
            if smooth:
                normals.append(_corner_normals(mesh, pose.R_a_from_b))
            if with_uv:
                uv = mesh.corner_uv
                uvs.append(np.zeros((len(mesh.faces), 3, 2)) if uv is None else uv)
            offset += len(mesh.vertices_m)
        textures.extend(mesh.part_textures or (None,) * parts)
        prefix = "" if k == 0 else f"{names[k - 1]}/"
        part_names.extend(prefix + n for n in mesh.part_names)
        part_materials.extend(mesh.part_materials)
        owner.extend([k + 1] * parts)
        for key, value in mesh.materials.items():
            materials.setdefault(key, value)
        part_offset += parts
    merged = TargetMesh(
        np.concatenate(verts),
        np.concatenate(faces),
        np.concatenate(index),
        tuple(part_names),
        tuple(part_materials),
        materials=materials,
        name=target.name,
        corner_normals=np.concatenate(normals) if smooth else None,
        corner_uv=np.concatenate(uvs) if with_uv else None,
        part_textures=tuple(textures) if textured else (),
    )
    return SceneMesh(
        merged,
        len(target.part_names),
        tuple(names),
        np.array(owner, dtype=np.uint8),
        tuple(pose for _, _, pose in objects),
    )


def objects_only(scene: SceneMesh) -> TargetMesh:
    """The merged mesh without the target's triangles, its part table kept whole (so part
    ids, and the object ids ``SceneMesh.object_id`` gives them, are those of the scene)."""
    mesh = scene.mesh
    keep = mesh.face_part_index >= scene.target_part_count
    return TargetMesh(
        mesh.vertices_m,
        mesh.faces[keep],
        mesh.face_part_index[keep],
        mesh.part_names,
        mesh.part_materials,
        materials=mesh.materials,
        name=f"{mesh.name} objects",
        corner_normals=None if mesh.corner_normals is None else mesh.corner_normals[keep],
        corner_uv=None if mesh.corner_uv is None else mesh.corner_uv[keep],
        part_textures=mesh.part_textures,
    )
