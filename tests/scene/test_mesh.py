"""TargetMesh: validation of the arrays, and bounds / keypoints on a hand-built unit cube."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.scene.materials import FIRST_MATERIALS
from satsight.scene.mesh import TargetMesh, merge_parts

ATOL_M = 1e-12

# Unit cube [0, 1]^3: vertex k has x = bit 0, y = bit 1, z = bit 2 of k.
CUBE_VERTICES_M = np.array([[(k >> 0) & 1, (k >> 1) & 1, (k >> 2) & 1] for k in range(8)], float)
# Two triangles per face, counter-clockwise seen from outside.
CUBE_FACES = np.array(
    [
        [0, 2, 1], [1, 2, 3],  # z = 0, normal -z
        [4, 5, 6], [5, 7, 6],  # z = 1, normal +z
        [0, 1, 4], [1, 5, 4],  # y = 0, normal -y
        [2, 6, 3], [3, 6, 7],  # y = 1, normal +y
        [0, 4, 2], [2, 4, 6],  # x = 0, normal -x
        [1, 3, 5], [3, 7, 5],  # x = 1, normal +x
    ]
)  # fmt: skip


def cube(**overrides) -> TargetMesh:
    """The unit cube in two parts: the z = 0 face ('bottom') and the rest ('sides')."""
    kwargs = {
        "vertices_m": CUBE_VERTICES_M,
        "faces": CUBE_FACES,
        "face_part_index": np.array([0, 0] + [1] * 10),
        "part_names": ("bottom", "sides"),
        "part_materials": ("black_crinkle", "mli_gold"),
        "name": "cube",
    }
    kwargs.update(overrides)
    return TargetMesh(**kwargs)


def test_cube_faces_point_outwards() -> None:
    # Guard for the fixture itself: every normal points away from the cube centre.
    v = CUBE_VERTICES_M[CUBE_FACES]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    outward = v.mean(axis=1) - 0.5
    assert np.all(np.einsum("ij,ij->i", normals, outward) > 0)


def test_bounds_center_extent_and_radius_of_unit_cube() -> None:
    mesh = cube()
    np.testing.assert_allclose(mesh.bounds_m, [[0, 0, 0], [1, 1, 1]], atol=ATOL_M)
    np.testing.assert_allclose(mesh.center_m, [0.5, 0.5, 0.5], atol=ATOL_M)
    np.testing.assert_allclose(mesh.extent_m, [1, 1, 1], atol=ATOL_M)
    assert mesh.bounding_radius_m == pytest.approx(math.sqrt(3) / 2, abs=ATOL_M)


def test_keypoints_are_corners_by_bits_then_centre() -> None:
    keypoints = cube().box_keypoints_body_m
    assert keypoints.shape == (9, 3)
    # Corner k of the bounding box of [0, 1]^3 is exactly vertex k of the hand-built cube.
    np.testing.assert_allclose(keypoints[:8], CUBE_VERTICES_M, atol=ATOL_M)
    np.testing.assert_allclose(keypoints[8], [0.5, 0.5, 0.5], atol=ATOL_M)


def test_keypoints_follow_a_shifted_box() -> None:
    mesh = cube(vertices_m=CUBE_VERTICES_M * [2.0, 3.0, 4.0] - [1.0, 1.0, 1.0])
    np.testing.assert_allclose(mesh.box_keypoints_body_m[0], [-1, -1, -1], atol=ATOL_M)
    np.testing.assert_allclose(mesh.box_keypoints_body_m[7], [1, 2, 3], atol=ATOL_M)
    np.testing.assert_allclose(mesh.box_keypoints_body_m[5], [1, -1, 3], atol=ATOL_M)  # bits x, z


def test_part_ids_start_at_one_and_summary_counts_triangles() -> None:
    mesh = cube()
    np.testing.assert_array_equal(mesh.part_ids, [1, 1] + [2] * 10)
    summary = mesh.summary()
    assert summary["triangle_count"] == 12 and summary["vertex_count"] == 8
    assert [p["triangle_count"] for p in summary["parts"]] == [2, 10]
    assert [p["part_id"] for p in summary["parts"]] == [1, 2]
    assert mesh.part_material(1) is FIRST_MATERIALS["mli_gold"]


def test_arrays_are_normalised_to_dtypes() -> None:
    mesh = cube(faces=CUBE_FACES.astype(np.int32), vertices_m=CUBE_VERTICES_M.astype(np.float32))
    assert mesh.vertices_m.dtype == np.float64
    assert mesh.faces.dtype == np.int64
    assert mesh.face_part_index.dtype == np.int32


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"vertices_m": np.zeros((0, 3))}, "no vertices"),
        ({"vertices_m": np.zeros((8, 2))}, "no vertices"),
        ({"faces": np.zeros((0, 3), int), "face_part_index": np.zeros(0)}, "no triangles"),
        ({"vertices_m": np.where(CUBE_VERTICES_M == 1, np.nan, 0.0)}, "non-finite"),
        ({"faces": np.where(CUBE_FACES == 7, 8, CUBE_FACES)}, r"outside 0\.\.7"),
        ({"faces": np.where(CUBE_FACES == 7, -1, CUBE_FACES)}, r"outside 0\.\.7"),
        ({"face_part_index": np.zeros(11)}, "one entry per triangle"),
        ({"part_materials": ("mli_gold",)}, "one material name is needed per part"),
        ({"face_part_index": np.full(12, 2)}, "parts that do not exist"),
        ({"part_materials": ("mli_gold", "unobtainium")}, "no definition: unobtainium"),
        ({"vertices_m": np.zeros((8, 3))}, "every triangle is degenerate"),
    ],
)
def test_invalid_meshes_are_refused_with_a_reason(overrides: dict, message: str) -> None:
    with pytest.raises(SatsightError, match=message) as error:
        cube(**overrides)
    assert "mesh 'cube'" in str(error.value)


def test_merge_parts_offsets_indices_and_keeps_order() -> None:
    tri_m = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    lifted_m = tri_m + np.array([0.0, 0.0, 1.0])
    mesh = merge_parts(
        [("a", "cfrp", tri_m, [[0, 1, 2]]), ("b", "white_paint", lifted_m, [[0, 1, 2]])]
    )
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [3, 4, 5]])
    np.testing.assert_array_equal(mesh.face_part_index, [0, 1])
    assert mesh.part_names == ("a", "b") and mesh.part_materials == ("cfrp", "white_paint")
    np.testing.assert_allclose(mesh.vertices_m[3:], lifted_m, atol=ATOL_M)


def test_merge_parts_without_parts_is_refused() -> None:
    with pytest.raises(SatsightError, match="has no parts"):
        merge_parts([], name="empty")
