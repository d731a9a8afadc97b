"""Shading normals and texture coordinates at the corners of triangles.

A smooth surface approximated by flat triangles shows its facets when it is shaded with
the triangles' own (geometric) normals. Shading normals are given per triangle corner and
interpolated over each triangle with the hit's barycentrics (Phong 1975, "Illumination for
computer generated pictures", CACM 18(6), the normal-vector interpolation). They come
from the file (OBJ ``vn``, glTF ``NORMAL``) or, where the file has none, from the crease
angle: a corner's normal averages the normals of the triangles around its vertex that lie
within the crease angle of its own triangle, each weighted by its angle at that vertex
(Thürmer & Wüthrich 1998, "Computing vertex normals from polygonal facets", Journal of
Graphics Tools 3(1)). Edges sharper than the crease angle stay sharp: a box keeps flat
faces, a 24-sided cylinder (15 degrees between facets) becomes round.

``DEFAULT_CREASE_ANGLE_DEG`` = 30 degrees: coarse tessellations of curved parts (a
12-sided cylinder, 30 degrees between facets, is the coarsest that still smooths) are
rounded while the right-angled edges of boxes, panels and brackets stay sharp.
"""

from __future__ import annotations

import math

import numpy as np

DEFAULT_CREASE_ANGLE_DEG = 30.0
# A corner whose normal differs from its face normal by less than this is flat.
_FLAT_COSINE = 1.0 - 1e-9
_PAIRS_PER_CHUNK = 1 << 20


def face_normals(vertices_m: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) unit geometric normals (right-hand rule on the corner order); 0 where the
    triangle is degenerate."""
    tri = vertices_m[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def corner_angles(vertices_m: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) interior angle (rad) of each triangle at each corner."""
    tri = vertices_m[faces]
    angles = np.zeros(faces.shape, dtype=np.float64)
    for k in range(3):
        a = tri[:, (k + 1) % 3] - tri[:, k]
        b = tri[:, (k + 2) % 3] - tri[:, k]
        # atan2(|a x b|, a.b) keeps its precision for thin triangles.
        angles[:, k] = np.arctan2(
            np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b)
        )
    return angles


def weld_groups(vertices_m: np.ndarray, tolerance_m: float | None = None) -> np.ndarray:
    """(N,) group index per vertex: vertices closer than ``tolerance_m`` on a grid share a
    group (files often repeat a position for each normal or texture coordinate)."""
    v = np.asarray(vertices_m, dtype=np.float64)
    if tolerance_m is None:
        extent = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
        tolerance_m = 1e-7 * extent + 1e-12
    keys = np.round((v - v.min(axis=0)) / tolerance_m).astype(np.int64)
    _, groups = np.unique(keys, axis=0, return_inverse=True)
    return groups.reshape(-1)


def crease_normals(
    vertices_m: np.ndarray, faces: np.ndarray, crease_angle_deg: float = DEFAULT_CREASE_ANGLE_DEG
) -> np.ndarray:
    """(F, 3, 3) unit shading normal at each corner of each triangle (see the module
    docstring). Vertices at the same position are treated as one, so a mesh split at
    texture seams still smooths across them; a degenerate triangle keeps a zero normal."""
    vertices_m = np.asarray(vertices_m, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    fn = face_normals(vertices_m, faces)
    weights = corner_angles(vertices_m, faces)
    cos_crease = math.cos(math.radians(float(crease_angle_deg)))
    corner_group = weld_groups(vertices_m)[faces].reshape(-1)  # (3F,)
    corner_face = np.repeat(np.arange(len(faces)), 3)
    corner_weighted = (fn[:, None, :] * weights[:, :, None]).reshape(-1, 3)

    order = np.argsort(corner_group, kind="stable")
    sorted_group = corner_group[order]
    starts = np.flatnonzero(np.r_[True, sorted_group[1:] != sorted_group[:-1]])
    sizes = np.diff(np.r_[starts, len(order)])
    group_of = np.repeat(np.arange(len(starts)), sizes)  # group rank of each sorted corner
    reps = sizes[group_of]  # pairs each sorted corner takes part in
    total = np.zeros((len(order), 3))
    first = 0
    while first < len(order):  # chunks of corners whose pairs fit in memory
        cum = np.cumsum(reps[first:])
        last = first + max(1, int(np.searchsorted(cum, _PAIRS_PER_CHUNK, side="right")))
        rep = reps[first:last]
        i = np.repeat(np.arange(first, last), rep)
        offset = np.arange(len(i)) - np.repeat(np.cumsum(rep) - rep, rep)
        j = starts[group_of[i]] + offset
        ci, cj = order[i], order[j]
        near = np.einsum("ij,ij->i", fn[corner_face[ci]], fn[corner_face[cj]]) >= cos_crease
        for axis in range(3):
            total[first:last, axis] = np.bincount(
                i[near] - first, weights=corner_weighted[cj[near], axis], minlength=last - first
            )
        first = last
    normals = np.zeros_like(total)
    normals[order] = total
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    fallback = np.repeat(fn, 3, axis=0)
    normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), fallback)
    return normals.reshape(-1, 3, 3)


def angle_weighted_vertex_normals(vertices_m: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N, 3) unit normal per vertex: the normals of the triangles using the vertex, each
    weighted by its interior angle there (Thürmer & Wüthrich 1998), with no crease angle
    and no welding (unlike ``crease_normals``). faces: (M, 3), counter-clockwise seen from
    outside. A vertex of no (non-degenerate) triangle gets a zero normal.

    The angles come from the arccos of the clipped cosine, not from ``corner_angles``'
    atan2: the two differ in the last bits, enough to change some printed digits of the
    BOP models (``satsight.dataset.export.bop_model``) that use these normals.
    """
    corners = vertices_m[faces]  # (M, 3, 3)
    unit_face_normals = face_normals(vertices_m, faces)
    normals = np.zeros_like(vertices_m)
    for k in range(3):
        a = corners[:, (k + 1) % 3] - corners[:, k]
        b = corners[:, (k + 2) % 3] - corners[:, k]
        cosine = np.einsum("ij,ij->i", a, b) / np.maximum(
            np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300
        )
        angle = np.arccos(np.clip(cosine, -1.0, 1.0))
        np.add.at(normals, faces[:, k], unit_face_normals * angle[:, None])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)


def corners_from_vertices(values: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-vertex values (N, k) -> per-corner values (F, 3, k)."""
    return np.asarray(values, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]


def unit_rows(vectors: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Vectors scaled to unit length; ``fallback`` (same shape) where the length is 0 or
    not finite."""
    v = np.asarray(vectors, dtype=np.float64)
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(length) & (length > 1e-12)
    return np.where(ok, v / np.where(ok, length, 1.0), fallback)


def is_flat(corner_normals: np.ndarray, vertices_m: np.ndarray, faces: np.ndarray) -> bool:
    """Whether every corner normal equals (or is opposite to) its face's geometric normal,
    so that interpolating them changes nothing."""
    fn = face_normals(vertices_m, faces)
    cos = np.abs(np.einsum("fkj,fj->fk", corner_normals, fn))
    return bool(np.all((cos >= _FLAT_COSINE) | (np.linalg.norm(fn, axis=1) == 0)[:, None]))


def box_uv(
    vertices_m: np.ndarray,
    faces: np.ndarray,
    size_uv_m: tuple[float, float],
    origin_m=(0.0, 0.0, 0.0),
    axes: dict[int, tuple[int, int]] | None = None,
) -> np.ndarray:
    """(F, 3, 2) planar texture coordinates: each triangle projected along the axis its
    normal is closest to. ``axes`` maps that axis (0 x, 1 y, 2 z) to the axes giving
    (u, v) (default x -> (y, z), y -> (x, z), z -> (x, y)); u = (p[a] - origin[a]) /
    size_u, v = (p[b] - origin[b]) / size_v, so one unit of (u, v) is one texture tile."""
    axes = axes or {0: (1, 2), 1: (0, 2), 2: (0, 1)}
    vertices_m = np.asarray(vertices_m, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    dominant = np.argmax(np.abs(face_normals(vertices_m, faces)), axis=1)
    a = np.array([axes[int(k)][0] for k in range(3)])[dominant]
    b = np.array([axes[int(k)][1] for k in range(3)])[dominant]
    p = vertices_m[faces] - np.asarray(origin_m, dtype=np.float64)  # (F, 3, 3)
    rows = np.arange(len(faces))[:, None]
    u = p[rows, np.arange(3)[None, :], a[:, None]] / size_uv_m[0]
    v = p[rows, np.arange(3)[None, :], b[:, None]] / size_uv_m[1]
    return np.stack([u, v], axis=-1)
