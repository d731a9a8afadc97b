"""Shading normals at triangle corners: crease angle, welding, merging, planar UVs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from satsight.errors import SatsightError
from satsight.scene.mesh import PartSurface, TargetMesh, merge_parts
from satsight.scene.normals import (
    DEFAULT_CREASE_ANGLE_DEG,
    angle_weighted_vertex_normals,
    box_uv,
    crease_normals,
    face_normals,
)

ATOL = 1e-12


def radial_cylinder(sections: int):
    mesh = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=sections)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_cylinder_sides_get_the_exact_radial_normal_and_caps_stay_flat() -> None:
    """At a vertex of a regular 24-gon the two side facets meet at 15 degrees, within the
    crease angle; their angle-weighted mean is the exact radial direction there. The
    caps meet the sides at 90 degrees and keep the axis as normal."""
    vertices, faces = radial_cylinder(24)
    normals = crease_normals(vertices, faces)
    fn = face_normals(vertices, faces)
    side = np.abs(fn[:, 2]) < 1e-9
    corners = vertices[faces[side]]  # (S, 3, 3)
    radial = corners * np.array([1.0, 1.0, 0.0])
    radial /= np.linalg.norm(radial, axis=-1, keepdims=True)
    np.testing.assert_allclose(normals[side], radial, atol=1e-9)
    np.testing.assert_allclose(normals[~side], np.repeat(fn[~side, None], 3, axis=1), atol=ATOL)


def test_crease_angle_below_the_facet_angle_keeps_facets_flat() -> None:
    vertices, faces = radial_cylinder(8)  # 45 degrees between side facets
    normals = crease_normals(vertices, faces, DEFAULT_CREASE_ANGLE_DEG)
    fn = face_normals(vertices, faces)
    np.testing.assert_allclose(normals, np.repeat(fn[:, None], 3, axis=1), atol=ATOL)
    smooth = crease_normals(vertices, faces, 50.0)
    assert not np.allclose(smooth, np.repeat(fn[:, None], 3, axis=1))


def test_vertices_repeated_at_one_position_are_smoothed_as_one() -> None:
    """Files split vertices at texture seams; smoothing must not see a crease there."""
    vertices, faces = radial_cylinder(24)
    split_v = vertices[faces].reshape(-1, 3)  # every corner its own vertex
    split_f = np.arange(len(split_v)).reshape(-1, 3)
    np.testing.assert_allclose(
        crease_normals(split_v, split_f), crease_normals(vertices, faces), atol=1e-12
    )


def test_icosphere_corner_normals_are_nearly_radial() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=2)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    normals = crease_normals(v, f)
    radial = v[f] / np.linalg.norm(v[f], axis=-1, keepdims=True)
    # The angle-weighted normal of a subdivided icosahedron is within 1 degree of radial;
    # the face normals are up to ~10 degrees off at the corners.
    assert np.degrees(np.arccos(np.clip((normals * radial).sum(-1), -1, 1))).max() < 1.0
    flat = face_normals(v, f)[:, None]
    assert np.degrees(np.arccos(np.clip((flat * radial).sum(-1), -1, 1))).max() > 8.0


def test_merge_keeps_corner_normals_only_where_a_part_is_smooth() -> None:
    box = trimesh.creation.box()
    tube_v, tube_f = radial_cylinder(32)
    flat = merge_parts([("box", "white_paint", box.vertices, box.faces)], crease_angle_deg=30)
    assert not flat.smooth  # a box has only 90-degree edges
    mixed = merge_parts(
        [
            ("box", "white_paint", box.vertices, box.faces),
            ("tube", "cfrp", tube_v + 3.0, tube_f),
        ],
        crease_angle_deg=30,
    )
    assert mixed.smooth and mixed.corner_normals.shape == (len(mixed.faces), 3, 3)
    box_faces = mixed.face_part_index == 0
    fn = face_normals(mixed.vertices_m, mixed.faces)
    np.testing.assert_allclose(
        mixed.corner_normals[box_faces], np.repeat(fn[box_faces, None], 3, axis=1), atol=ATOL
    )


def test_file_normals_are_normalised_and_kept_per_corner() -> None:
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    given = np.array([[0, 0, 2.0], [0.1, 0, 1], [0, 0, 1], [0, 0.2, 1]])
    mesh = merge_parts([("plate", "white_paint", v, f, PartSurface(vertex_normals=given))])
    want = given / np.linalg.norm(given, axis=1, keepdims=True)
    np.testing.assert_allclose(mesh.corner_normals, want[f], atol=ATOL)


def test_target_mesh_refuses_corner_arrays_of_the_wrong_shape() -> None:
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    with pytest.raises(SatsightError, match="corner_normals must be finite"):
        TargetMesh(v, [[0, 1, 2]], [0], ("p",), ("white_paint",), corner_normals=np.ones((1, 3)))
    with pytest.raises(SatsightError, match="corner_uv"):
        TargetMesh(v, [[0, 1, 2]], [0], ("p",), ("white_paint",), corner_uv=np.ones((2, 3, 2)))


def test_box_uv_projects_each_face_along_its_dominant_axis() -> None:
    box = trimesh.creation.box(extents=[0.02, 2.0, 1.0])
    uv = box_uv(box.vertices, box.faces, (0.5, 0.25), origin_m=(0.0, -1.0, -0.5))
    fn = face_normals(np.asarray(box.vertices), np.asarray(box.faces))
    plus_x = fn[:, 0] > 0.5
    corners = np.asarray(box.vertices)[np.asarray(box.faces)[plus_x]]
    np.testing.assert_allclose(uv[plus_x, :, 0], (corners[..., 1] + 1.0) / 0.5, atol=ATOL)
    np.testing.assert_allclose(uv[plus_x, :, 1], (corners[..., 2] + 0.5) / 0.25, atol=ATOL)
    assert uv[plus_x].max(axis=(0, 1)) == pytest.approx([4.0, 4.0])  # 4 x 4 tiles


def test_crease_angle_of_exactly_the_facet_angle_is_inclusive() -> None:
    sections = 12  # 30 degrees between side facets
    vertices, faces = radial_cylinder(sections)
    normals = crease_normals(vertices, faces, 30.0 + 1e-9)
    fn = face_normals(vertices, faces)
    side = np.abs(fn[:, 2]) < 1e-9
    tilt = np.degrees(np.arccos(np.clip((normals[side] * fn[side, None]).sum(-1), -1, 1)))
    assert tilt.max() == pytest.approx(15.0, abs=1e-6)
    assert math.isclose(DEFAULT_CREASE_ANGLE_DEG, 30.0)


def test_angle_weighted_vertex_normals_of_a_box_point_along_its_diagonals() -> None:
    """Each box corner meets three faces at 90 degrees in total each (however the face is
    split into triangles), so its normal is the exact diagonal; an unused vertex gets 0."""
    box = trimesh.creation.box(extents=[2.0, 2.0, 2.0])
    vertices = np.vstack([np.asarray(box.vertices), [[5.0, 5.0, 5.0]]])
    normals = angle_weighted_vertex_normals(vertices, np.asarray(box.faces))
    diagonal = vertices[:-1] / np.linalg.norm(vertices[:-1], axis=1, keepdims=True)
    np.testing.assert_allclose(normals[:-1], diagonal, atol=ATOL)
    np.testing.assert_array_equal(normals[-1], 0.0)
