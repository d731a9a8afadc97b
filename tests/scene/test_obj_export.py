"""OBJ + MTL writer: file layout, material values, name checks, speed."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from satsight.errors import SatsightError
from satsight.scene.materials import FIRST_MATERIALS
from satsight.scene.mesh import TargetMesh, merge_parts
from satsight.scene.obj_export import phong_exponent, write_obj
from satsight.scene.procedural import generate_satellite

MTL_DIGITS = 1e-6  # the MTL holds 6 decimals


def two_triangles_sharing_an_edge() -> TargetMesh:
    """Two parts that share two vertices: a triangle in z = 0 and one folded up."""
    vertices_m = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]])
    return TargetMesh(
        vertices_m=vertices_m,
        faces=np.array([[0, 1, 2], [1, 3, 2]]),
        face_part_index=np.array([0, 1]),
        part_names=("floor", "roof"),
        part_materials=("cfrp", "mli_gold"),
        name="fold",
    )


def read_mtl(path: Path) -> dict[str, dict[str, list[float]]]:
    entries: dict[str, dict[str, list[float]]] = {}
    current: dict[str, list[float]] = {}
    for line in path.read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        key, *values = line.split()
        if key == "newmtl":
            current = entries[values[0]] = {}
        else:
            current[key] = [float(v) for v in values]
    return entries


def test_obj_has_header_mtllib_and_one_object_per_part(tmp_path: Path) -> None:
    mesh = generate_satellite("two_wings", 2)
    obj_path, mtl_path = write_obj(mesh, tmp_path / "sat.obj")
    assert (obj_path, mtl_path) == (tmp_path / "sat.obj", tmp_path / "sat.mtl")
    lines = obj_path.read_text().splitlines()
    header = [line for line in lines if line.startswith("#")]
    assert any("units: metres" in line for line in header)
    assert any("+z telescope boresight" in line for line in header)
    assert "mtllib sat.mtl" in lines
    objects = [line[2:] for line in lines if line.startswith("o ")]
    materials = [line[7:] for line in lines if line.startswith("usemtl ")]
    assert tuple(objects) == mesh.part_names
    assert tuple(materials) == mesh.part_materials
    faces = np.array([line.split()[1:] for line in lines if line.startswith("f ")], dtype=int)
    vertex_count = sum(line.startswith("v ") for line in lines)
    assert len(faces) == len(mesh.faces)
    assert faces.min() == 1 and faces.max() == vertex_count  # 1-based, all in range


def test_vertices_shared_by_parts_are_written_once_per_part(tmp_path: Path) -> None:
    obj_path, _ = write_obj(two_triangles_sharing_an_edge(), tmp_path / "fold.obj")
    lines = obj_path.read_text().splitlines()
    assert sum(line.startswith("v ") for line in lines) == 6
    faces = [line for line in lines if line.startswith("f ")]
    assert faces == ["f 1 2 3", "f 4 6 5"]  # roof: vertices 1, 3, 2 -> its own 4, 5, 6


def test_mtl_holds_each_used_material_once_with_pbr_values(tmp_path: Path) -> None:
    mesh = generate_satellite("two_wings_dish", 4)
    _, mtl_path = write_obj(mesh, tmp_path / "sat.obj")
    entries = read_mtl(mtl_path)
    assert list(entries) == list(dict.fromkeys(mesh.part_materials))
    for name, values in entries.items():
        m = FIRST_MATERIALS[name]
        np.testing.assert_allclose(values["Kd"], m.base_color_rgb, atol=MTL_DIGITS)
        np.testing.assert_allclose(values["Ks"], m.ks_rgb, atol=MTL_DIGITS)
        assert values["Pm"] == pytest.approx([m.metallic], abs=MTL_DIGITS)
        assert values["Pr"] == pytest.approx([m.roughness], abs=MTL_DIGITS)
        assert values["Ni"] == pytest.approx([m.ior], abs=MTL_DIGITS)
        assert values["d"] == pytest.approx([m.alpha], abs=MTL_DIGITS)
        assert values["Ns"] == pytest.approx([phong_exponent(m.roughness)], abs=1e-4)


def test_phong_exponent_of_roughness() -> None:
    assert phong_exponent(1.0) == 0.0  # 2 / 1 - 2
    assert phong_exponent(0.5) == pytest.approx(30.0)  # 2 / 0.0625 - 2
    assert phong_exponent(0.0) == 1000.0  # mirror: clipped
    assert phong_exponent(0.02) == 1000.0


def test_trimesh_reads_the_written_file(tmp_path: Path) -> None:
    obj_path, _ = write_obj(generate_satellite("one_wing", 0), tmp_path / "sat.obj")
    scene = trimesh.load_scene(obj_path, process=False, split_objects=True)
    assert "bus_mli" in "".join(scene.geometry)


def test_output_path_must_be_an_obj_in_an_existing_folder(tmp_path: Path) -> None:
    mesh = two_triangles_sharing_an_edge()
    with pytest.raises(SatsightError, match=r"must end in \.obj"):
        write_obj(mesh, tmp_path / "fold.ply")
    with pytest.raises(SatsightError, match="does not exist; create it first"):
        write_obj(mesh, tmp_path / "missing" / "fold.obj")


@pytest.mark.parametrize(
    ("part_name", "material_name", "kind"),
    [("solar wing", "cfrp", "part"), ("wing", "gold foil", "material"), ("", "cfrp", "part")],
)
def test_names_with_white_space_are_refused(
    tmp_path: Path, part_name: str, material_name: str, kind: str
) -> None:
    tri_m = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    library = {material_name: FIRST_MATERIALS["cfrp"]}
    mesh = merge_parts([(part_name, material_name, tri_m, [[0, 1, 2]])], materials=library)
    with pytest.raises(SatsightError, match=f"cannot write {kind} name"):
        write_obj(mesh, tmp_path / "bad.obj")


def test_writing_30k_triangles_is_fast(tmp_path: Path) -> None:
    sphere = trimesh.creation.icosphere(subdivisions=5)  # 20480 triangles
    tiles = [("a", "cfrp", sphere.vertices, sphere.faces)]
    tiles.append(("b", "white_paint", sphere.vertices + 3.0, sphere.faces[:10_000]))
    mesh = merge_parts(tiles)
    start = time.perf_counter()
    obj_path, _ = write_obj(mesh, tmp_path / "big.obj")
    assert time.perf_counter() - start < 2.0
    assert sum(line.startswith("f ") for line in obj_path.read_text().splitlines()) == 30_480
