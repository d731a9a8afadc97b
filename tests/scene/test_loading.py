"""load_mesh: OBJ round trip, MTL / glTF materials, scene-graph transforms, refusals."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from trimesh.visual import TextureVisuals
from trimesh.visual.material import PBRMaterial

from satsight.errors import SatsightError
from satsight.scene.loading import load_mesh
from satsight.scene.materials import DEFAULT_MATERIAL_NAME, FIRST_MATERIALS
from satsight.scene.obj_export import write_obj
from satsight.scene.procedural import SATELLITE_CLASSES, generate_satellite

OBJ_DIGITS_M = 1e-6  # 9 significant digits on a <= 10 m satellite
FLOAT32_M = 1e-6  # glTF positions are float32
COLOR_STEP = 1.0 / 255.0  # trimesh stores glTF base colours as 8-bit
ATOL = 1e-12


def assert_same_values(got, want, atol: float = 1e-6) -> None:
    np.testing.assert_allclose(got.base_color_rgb, want.base_color_rgb, atol=atol)
    for key in ("metallic", "roughness", "ior", "alpha"):
        assert getattr(got, key) == pytest.approx(getattr(want, key), abs=atol), key


def write_text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def glb_bytes(document: dict) -> bytes:
    """A GLB of a 12-byte header and one JSON chunk (no binary chunk)."""
    chunk = json.dumps(document).encode()
    chunk += b" " * (-len(chunk) % 4)
    header = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(chunk))
    return header + struct.pack("<I4s", len(chunk), b"JSON") + chunk


def pbr(name: str, rgba, metallic: float, roughness: float, **kwargs) -> TextureVisuals:
    material = PBRMaterial(
        name=name,
        baseColorFactor=rgba,
        metallicFactor=metallic,
        roughnessFactor=roughness,
        **kwargs,
    )
    return TextureVisuals(material=material)


# --- OBJ --------------------------------------------------------------------------------------
@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_obj_round_trip_keeps_parts_materials_and_vertices(
    tmp_path: Path, satellite_class: str
) -> None:
    original = generate_satellite(satellite_class, 3)
    obj_path, _ = write_obj(original, tmp_path / "sat.obj")
    loaded = load_mesh(obj_path)
    assert loaded.part_names == original.part_names
    assert loaded.part_materials == original.part_materials
    assert len(loaded.faces) == len(original.faces)
    np.testing.assert_allclose(loaded.vertices_m, original.vertices_m, rtol=0, atol=OBJ_DIGITS_M)
    np.testing.assert_array_equal(loaded.faces, original.faces)
    np.testing.assert_array_equal(loaded.face_part_index, original.face_part_index)
    for name in set(loaded.part_materials):  # the MTL's values (written from the library)
        assert_same_values(loaded.materials[name], FIRST_MATERIALS[name])
        assert loaded.materials[name].source.startswith("sat.obj")


def test_obj_materials_rebuilt_from_mtl_without_library(tmp_path: Path) -> None:
    original = generate_satellite("two_wings_dish", 1)
    obj_path, _ = write_obj(original, tmp_path / "sat.obj")
    loaded = load_mesh(obj_path, materials={})
    assert set(loaded.materials) == set(original.part_materials)
    for name in set(original.part_materials):
        assert_same_values(loaded.materials[name], FIRST_MATERIALS[name])
        assert "sat.obj" in loaded.materials[name].source


def test_user_library_is_used_where_asked_for(tmp_path: Path) -> None:
    original = generate_satellite("one_wing", 5)
    obj_path, _ = write_obj(original, tmp_path / "sat.obj")
    shiny = FIRST_MATERIALS["brushed_aluminium"]
    library = {"shiny": shiny}
    loaded = load_mesh(obj_path, materials=library, builtin_materials={"solar_cell": "shiny"})
    cells = [n for n in loaded.part_names if n.endswith("_cells")]
    for name in cells:
        assert loaded.part_materials[loaded.part_names.index(name)] == "shiny"
    assert loaded.materials["shiny"] is shiny
    assert "solar_cell" not in loaded.part_materials
    assert loaded.materials["cfrp"].source.startswith("sat.obj")  # not asked for: MTL


def test_scale_multiplies_obj_vertices(tmp_path: Path) -> None:
    original = generate_satellite("body_mounted", 2)
    obj_path, _ = write_obj(original, tmp_path / "sat.obj")
    loaded = load_mesh(obj_path, scale_m=1e-3)
    np.testing.assert_allclose(loaded.vertices_m, original.vertices_m * 1e-3, atol=1e-9)


OBJ_TWO_MATERIALS = """\
mtllib parts.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
o panel
usemtl solar_cell
f 1 2 3 4
usemtl kapton
f 1 2 5
o strut
f 2 3 5
"""
MTL_KAPTON = """\
newmtl kapton
Kd 0.9 0.6 0.1
Ns 30
Tr 0.25
Ni 1.7
newmtl solar_cell
Kd 1 1 1
"""


def test_obj_parts_split_by_object_and_material(tmp_path: Path) -> None:
    write_text(tmp_path / "parts.mtl", MTL_KAPTON)
    mesh = load_mesh(write_text(tmp_path / "parts.obj", OBJ_TWO_MATERIALS))
    # One object with two materials gives two parts; usemtl carries over to the next object.
    assert mesh.part_names == ("panel_solar_cell", "panel_kapton", "strut")
    assert mesh.part_materials == ("solar_cell", "kapton", "kapton")
    np.testing.assert_array_equal(mesh.face_part_index, [0, 0, 1, 2])  # the quad: 2 triangles
    assert mesh.materials["solar_cell"].base_color_rgb == (1.0, 1.0, 1.0)  # the file wins
    kapton = mesh.materials["kapton"]
    assert kapton.base_color_rgb == (0.9, 0.6, 0.1)
    assert kapton.ior == 1.7
    assert kapton.alpha == pytest.approx(0.75, abs=ATOL)  # d = 1 - Tr
    assert kapton.roughness == pytest.approx((2.0 / 32.0) ** 0.25, abs=ATOL)  # from Ns = 30
    assert kapton.metallic == 0.0  # no Pm: dielectric


def test_obj_without_mtl_keeps_material_names_with_default_values(tmp_path: Path) -> None:
    mesh = load_mesh(write_text(tmp_path / "parts.obj", OBJ_TWO_MATERIALS))
    assert mesh.part_materials == ("solar_cell", "kapton", "kapton")
    default = FIRST_MATERIALS[DEFAULT_MATERIAL_NAME]
    assert mesh.materials["kapton"].base_color_rgb == default.base_color_rgb
    assert "no definition" in mesh.materials["kapton"].source


def test_obj_groups_name_parts_and_faces_without_material_get_the_default(
    tmp_path: Path,
) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng left\nf 1 2 3\ng right\nf 1 3 4\n"
    mesh = load_mesh(write_text(tmp_path / "groups.obj", text))
    assert mesh.part_names == ("left", "right")
    assert mesh.part_materials == (DEFAULT_MATERIAL_NAME, DEFAULT_MATERIAL_NAME)


# --- glTF -------------------------------------------------------------------------------------
def test_glb_nodes_become_parts_with_pbr_materials_and_transforms(tmp_path: Path) -> None:
    body = trimesh.creation.box(extents=[1.0, 2.0, 3.0])
    body.visual = pbr("gold_foil", [0.8, 0.4, 0.2, 1.0], metallic=0.9, roughness=0.3)
    panel = trimesh.creation.box(extents=[2.0, 1.0, 0.1])
    panel.visual = pbr("kapton", [0.2, 0.6, 1.0, 0.4], 0.1, 0.7, alphaMode="BLEND")
    lens = trimesh.creation.cylinder(radius=0.1, height=0.02)
    lens.visual = pbr("optical_lens", [1.0, 1.0, 1.0, 1.0], 0.5, 0.5)
    panel_pose = trimesh.transformations.translation_matrix([5.0, 0.0, 1.0])
    panel_pose = panel_pose @ trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1])
    scene = trimesh.Scene()
    scene.add_geometry(body, node_name="body", geom_name="body_mesh")
    scene.add_geometry(panel, node_name="panel", geom_name="panel_mesh", transform=panel_pose)
    scene.add_geometry(lens, node_name="lens", geom_name="lens_mesh")
    glb = tmp_path / "sat.glb"
    scene.export(glb)

    mesh = load_mesh(glb)
    assert mesh.part_names == ("body", "panel", "lens")  # node order
    assert mesh.part_materials == ("gold_foil", "kapton", "optical_lens")
    assert len(mesh.faces) == len(body.faces) + len(panel.faces) + len(lens.faces)
    panel_vertices = mesh.vertices_m[np.unique(mesh.faces[mesh.face_part_index == 1])]
    want = trimesh.transformations.transform_points(panel.vertices, panel_pose)
    np.testing.assert_allclose(
        np.sort(panel_vertices, axis=0), np.sort(want, axis=0), atol=FLOAT32_M
    )
    np.testing.assert_allclose(mesh.bounds_m, [[-0.5, -1.0, -1.5], [5.5, 1.0, 1.5]], atol=FLOAT32_M)

    gold, kapton = mesh.materials["gold_foil"], mesh.materials["kapton"]
    assert (gold.metallic, gold.roughness) == pytest.approx((0.9, 0.3), abs=ATOL)
    np.testing.assert_allclose(gold.base_color_rgb, [0.8, 0.4, 0.2], atol=COLOR_STEP)
    assert gold.alpha == 1.0 and gold.ior == 1.5  # OPAQUE; glTF's default IOR
    assert (kapton.metallic, kapton.roughness) == pytest.approx((0.1, 0.7), abs=ATOL)
    assert kapton.alpha == pytest.approx(0.4, abs=COLOR_STEP)  # BLEND: opacity from alpha
    lens_material = mesh.materials["optical_lens"]  # the file wins over the built-in name
    assert (lens_material.metallic, lens_material.roughness) == pytest.approx((0.5, 0.5))


def gltf_document(node_scale, material: dict | None) -> dict:
    """A .gltf (buffer as data URI) with one node 'arm' whose mesh has two primitives."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    first = np.array([0, 1, 2], dtype=np.uint32)  # in z = 0, normal +z
    second = np.array([0, 3, 1], dtype=np.uint32)  # in y = 0, normal -y
    data = positions.tobytes() + first.tobytes() + second.tobytes()
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    primitives = [
        {"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
        {"attributes": {"POSITION": 0}, "indices": 2},
    ]
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "root", "children": [1], "translation": [10.0, 0.0, 0.0]},
            {"name": "arm", "mesh": 0, "scale": node_scale},
        ],
        "meshes": [{"name": "arm_mesh", "primitives": primitives}],
        "materials": [material],
        "extensionsUsed": ["KHR_materials_ior"],
        "buffers": [{"byteLength": len(data), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12},
            {"buffer": 0, "byteOffset": 60, "byteLength": 12},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [0, 0, 0],
                "max": [1, 1, 1],
            },
            {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5125, "count": 3, "type": "SCALAR"},
        ],
    }


def test_gltf_primitives_parent_transform_mirror_and_ior(tmp_path: Path) -> None:
    material = {
        "name": "anodised",
        "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.3, 0.4, 0.5], "metallicFactor": 0.25},
        "alphaMode": "BLEND",
        "extensions": {"KHR_materials_ior": {"ior": 1.33}},
    }
    document = gltf_document([1.0, 1.0, -1.0], material)  # a mirror in z
    mesh = load_mesh(write_text(tmp_path / "arm.gltf", json.dumps(document)))
    assert mesh.part_names == ("arm_prim0", "arm_prim1")
    assert mesh.part_materials == ("anodised", DEFAULT_MATERIAL_NAME)
    np.testing.assert_allclose(mesh.bounds_m, [[10, 0, -1], [11, 1, 0]], atol=FLOAT32_M)
    # The mirror turns the first triangle over; its winding is flipped so it faces -z.
    v = mesh.vertices_m[mesh.faces[0]]
    normal = np.cross(v[1] - v[0], v[2] - v[0])
    np.testing.assert_allclose(normal / np.linalg.norm(normal), [0, 0, -1], atol=ATOL)
    anodised = mesh.materials["anodised"]  # exact values from the JSON, not 8-bit
    assert anodised.base_color_rgb == (0.2, 0.3, 0.4)
    assert (anodised.metallic, anodised.roughness) == (0.25, 1.0)  # roughness: glTF default
    assert (anodised.alpha, anodised.ior) == (0.5, 1.33)


def test_gltf_unnamed_instanced_nodes_take_the_mesh_name(tmp_path: Path) -> None:
    document = gltf_document([1.0, 1.0, 1.0], {"pbrMetallicRoughness": {}})
    for node in document["nodes"]:
        del node["name"]
    document["nodes"].append({"mesh": 0, "translation": [0.0, 5.0, 0.0]})  # a second instance
    document["scenes"][0]["nodes"].append(2)
    mesh = load_mesh(write_text(tmp_path / "unnamed.gltf", json.dumps(document)))
    assert mesh.part_names == (
        "arm_mesh_prim0",
        "arm_mesh_prim1",
        "arm_mesh_prim0_2",
        "arm_mesh_prim1_2",
    )
    # The unnamed material is named after the file, once for both instances.
    assert mesh.part_materials[0] == mesh.part_materials[2] == "unnamed_material_0"
    np.testing.assert_allclose(mesh.bounds_m, [[0, 0, 0], [11, 6, 1]], atol=FLOAT32_M)


def test_material_fallbacks_are_logged(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\ng bare\nf 1 2 3\ng named\nusemtl ghost\nf 1 3 2\n"
    with caplog.at_level("WARNING", logger="satsight.scene.loading"):
        load_mesh(write_text(tmp_path / "fallback.obj", text))
    assert "1 part(s) have no material (bare)" in caplog.text
    assert "material 'ghost' has no definition" in caplog.text


# --- refusals ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("declaration", "label"),
    [
        ({"extensionsRequired": ["KHR_draco_mesh_compression"]}, "Draco"),
        ({"extensionsUsed": ["KHR_draco_mesh_compression"]}, "Draco"),
        ({"extensionsRequired": ["EXT_meshopt_compression"]}, "meshopt"),
    ],
)
def test_compressed_glb_is_refused(tmp_path: Path, declaration: dict, label: str) -> None:
    glb = tmp_path / "compressed.glb"
    glb.write_bytes(glb_bytes({"asset": {"version": "2.0"}, **declaration}))
    with pytest.raises(SatsightError, match=f"uses {label} mesh compression") as error:
        load_mesh(glb)
    assert "without mesh compression" in str(error.value)


def test_compressed_gltf_is_refused_even_undeclared(tmp_path: Path) -> None:
    document = gltf_document([1.0, 1.0, 1.0], {"name": "x"})
    primitive = document["meshes"][0]["primitives"][0]
    primitive["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {}}}
    with pytest.raises(SatsightError, match="Draco"):
        load_mesh(write_text(tmp_path / "arm.gltf", json.dumps(document)))


def test_not_a_glb_is_refused(tmp_path: Path) -> None:
    glb = tmp_path / "fake.glb"
    glb.write_bytes(b"solid ascii stl pretending to be glb")
    with pytest.raises(SatsightError, match="not a binary glTF"):
        load_mesh(glb)
    with pytest.raises(SatsightError, match="broken glTF JSON"):
        load_mesh(write_text(tmp_path / "broken.gltf", "{not json"))


@pytest.mark.parametrize(
    "text",
    ["", "# only a comment\n", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "v 0 0 0\nv 1 0 0\nl 1 2\n"],
)
def test_obj_without_triangles_is_refused(tmp_path: Path, text: str) -> None:
    with pytest.raises(SatsightError, match="no triangles"):
        load_mesh(write_text(tmp_path / "empty.obj", text))


def test_point_cloud_glb_is_refused(tmp_path: Path) -> None:
    cloud = trimesh.PointCloud(np.random.default_rng(0).uniform(size=(10, 3)))
    glb = tmp_path / "cloud.glb"
    trimesh.Scene(cloud).export(glb)
    with pytest.raises(SatsightError, match="only points or lines"):
        load_mesh(glb)


def test_missing_file_and_unsupported_type_are_refused(tmp_path: Path) -> None:
    with pytest.raises(SatsightError, match="does not exist"):
        load_mesh(tmp_path / "missing.obj")
    stl = tmp_path / "model.stl"
    trimesh.creation.box().export(stl)
    with pytest.raises(SatsightError, match=r"unsupported file type '\.stl'.*\.obj, \.gltf, \.glb"):
        load_mesh(stl)


@pytest.mark.parametrize("scale_m", [0.0, -1.0, float("nan"), float("inf")])
def test_scale_must_be_positive_and_finite(tmp_path: Path, scale_m: float) -> None:
    obj_path, _ = write_obj(generate_satellite("one_wing", 0), tmp_path / "sat.obj")
    with pytest.raises(SatsightError, match="scale_m must be a positive number"):
        load_mesh(obj_path, scale_m=scale_m)


def test_white_space_in_gltf_names_becomes_underscores_and_writes_as_obj(tmp_path: Path) -> None:
    """Names like "Solar Panel" are common in glTF files; they must survive the OBJ model
    written beside a dataset, so white space becomes '_' (names stay unique)."""
    panel = trimesh.creation.box(extents=[2.0, 1.0, 0.1])
    panel.visual = pbr("Blue Cells", [0.1, 0.1, 0.5, 1.0], 0.0, 0.2)
    other = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    other.visual = pbr("Blue_Cells", [0.9, 0.9, 0.9, 1.0], 1.0, 0.4)
    scene = trimesh.Scene()
    scene.add_geometry(panel, node_name="Solar Panel", geom_name="a")
    scene.add_geometry(other, node_name="Solar_Panel", geom_name="b")
    glb = tmp_path / "spaced.glb"
    scene.export(glb)

    mesh = load_mesh(glb)
    assert all(" " not in n for n in mesh.part_names + mesh.part_materials)
    assert len(set(mesh.part_names)) == 2 and len(set(mesh.part_materials)) == 2
    assert set(mesh.part_names) >= {"Solar_Panel"}
    # the two materials keep their own values after renaming
    metallic = sorted(mesh.materials[m].metallic for m in mesh.part_materials)
    assert metallic == pytest.approx([0.0, 1.0], abs=ATOL)
    obj, _ = write_obj(mesh, tmp_path / "model.obj")
    again = load_mesh(obj)
    assert again.part_names == mesh.part_names
    assert again.part_materials == mesh.part_materials
