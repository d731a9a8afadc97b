"""Loading surfaces: normals, texture coordinates and textures from OBJ + MTL + PNG and glTF;
the file's material values win over built-in names unless a built-in is asked for."""

from __future__ import annotations

import io
import json
import logging
import struct
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from satsight.config.scenario import MeshTargetConfig
from satsight.errors import SatsightError
from satsight.scene.loading import load_mesh
from satsight.scene.materials import FIRST_MATERIALS

ATOL = 1e-12
FLOAT32 = 1e-6

PLATE_V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
PLATE_F = np.array([[0, 1, 2], [0, 2, 3]])


def png_bytes(pixels: np.ndarray) -> bytes:
    out = io.BytesIO()
    Image.fromarray(pixels).save(out, format="PNG")
    return out.getvalue()


def test_pixels(seed: int, shape=(4, 8)) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, size=(*shape, 3), dtype=np.uint8)


test_pixels.__test__ = False  # a helper, not a test


# --- OBJ -----------------------------------------------------------------------------------
PLATE_OBJ = """\
mtllib plate.mtl
o plate
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
vn 0.1 0 1
usemtl {material}
f 1/1/1 2/2/2 3/3/1
f 1/1/1 3/3/1 4/4/2
"""


def write_obj_plate(folder: Path, material: str, mtl: str, pixels=None) -> Path:
    if pixels is not None:
        Image.fromarray(pixels).save(folder / "paint.png")
    (folder / "plate.mtl").write_text(mtl)
    path = folder / "plate.obj"
    path.write_text(PLATE_OBJ.format(material=material))
    return path


def test_obj_normals_uv_and_map_kd_load(tmp_path: Path) -> None:
    pixels = test_pixels(1)
    mtl = "newmtl paint\nKd 0.5 0.5 0.5\nmap_Kd paint.png\n"
    mesh = load_mesh(write_obj_plate(tmp_path, "paint", mtl, pixels))
    # Normals from vn (normalised) and texture coordinates from vt, at each corner.
    vn = np.array([[0, 0, 1.0], [0.1, 0, 1]])
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    want_by_position = {(0, 0, 0): vn[0], (1, 0, 0): vn[1], (1, 1, 0): vn[0], (0, 1, 0): vn[1]}
    for f, tri in enumerate(mesh.vertices_m[mesh.faces]):
        for k, p in enumerate(tri):
            want = want_by_position[tuple(p)]
            np.testing.assert_allclose(mesh.corner_normals[f, k], want, atol=ATOL)
            np.testing.assert_allclose(mesh.corner_uv[f, k], p[:2], atol=ATOL)  # vt = (x, y)
    textures = mesh.part_texture(0)
    np.testing.assert_array_equal(textures.base_color.pixels, pixels)
    assert textures.base_color.encoding == "srgb" and textures.factors == "multiply"
    assert mesh.part_material(0).base_color_rgb == (0.5, 0.5, 0.5)  # Kd multiplies map_Kd


def test_obj_without_normals_gets_crease_normals_or_flat(tmp_path: Path) -> None:
    import trimesh

    tube = trimesh.creation.cylinder(radius=0.5, height=1.0, sections=32)
    path = tmp_path / "tube.obj"
    path.write_text(
        "o tube\n"
        + "".join(f"v {x} {y} {z}\n" for x, y, z in tube.vertices)
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in tube.faces)
    )
    smooth = load_mesh(path)
    assert smooth.smooth
    flat = load_mesh(path, crease_angle_deg=0.0)
    assert not flat.smooth
    with pytest.raises(SatsightError, match="crease_angle_deg"):
        load_mesh(path, crease_angle_deg=200.0)


def test_obj_material_named_like_a_builtin_keeps_the_file_values(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The defect: ``usemtl white_paint`` with ``Kd 0.1`` loaded as the built-in 0.85."""
    mtl = "newmtl white_paint\nKd 0.1 0.1 0.1\nPr 0.4\n"
    path = write_obj_plate(tmp_path, "white_paint", mtl)
    with caplog.at_level(logging.INFO, logger="satsight.scene.loading"):
        mesh = load_mesh(path)
    material = mesh.materials["white_paint"]
    assert material.base_color_rgb == (0.1, 0.1, 0.1)
    assert material.roughness == pytest.approx(0.4)
    assert material.source.startswith("plate.obj")
    assert "materials from the file: white_paint; built-in (target.mesh.materials): none" in (
        caplog.text
    )


@pytest.mark.parametrize("key", ["white_paint", "plate"])
def test_builtin_material_is_used_where_asked_for(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, key: str
) -> None:
    """By the file's material name or by the part's name."""
    mtl = "newmtl white_paint\nKd 0.1 0.1 0.1\nmap_Kd paint.png\n"
    path = write_obj_plate(tmp_path, "white_paint", mtl, test_pixels(2))
    with caplog.at_level(logging.INFO, logger="satsight.scene.loading"):
        mesh = load_mesh(path, builtin_materials={key: "white_paint"})
    assert mesh.part_material(0) is FIRST_MATERIALS["white_paint"]
    assert mesh.part_material(0).base_color_rgb == (0.85, 0.85, 0.82)
    assert not mesh.textured  # the built-in replaces the file's colour texture
    assert "built-in (target.mesh.materials): plate (white_paint -> white_paint)" in caplog.text


def test_builtin_requests_that_match_nothing_are_refused(tmp_path: Path) -> None:
    path = write_obj_plate(tmp_path, "white_paint", "newmtl white_paint\nKd 0.1 0.1 0.1\n")
    with pytest.raises(SatsightError, match="neither a part nor a material"):
        load_mesh(path, builtin_materials={"radiator": "white_paint"})
    with pytest.raises(SatsightError, match="unknown built-in material"):
        load_mesh(path, builtin_materials={"plate": "unobtainium"})


def test_undefined_material_named_like_a_builtin_says_how_to_ask_for_it(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "plate.obj"
    path.write_text(PLATE_OBJ.format(material="solar_cell").replace("mtllib plate.mtl\n", ""))
    with caplog.at_level(logging.WARNING, logger="satsight.scene.loading"):
        mesh = load_mesh(path)
    assert mesh.part_material(0).base_color_rgb == FIRST_MATERIALS["instrument_grey"].base_color_rgb
    assert "target.mesh.materials: {solar_cell: solar_cell}" in caplog.text


def test_scenario_key_names_builtin_materials() -> None:
    config = MeshTargetConfig(path="x.obj", materials={"white_paint": "white_paint"})
    assert config.materials == {"white_paint": "white_paint"}
    assert config.crease_angle_deg == 30.0
    with pytest.raises(ValueError, match="unknown material"):
        MeshTargetConfig(path="x.obj", materials={"a": "unobtainium"})


# --- glTF ----------------------------------------------------------------------------------
def glb(document: dict, binary: bytes) -> bytes:
    """A GLB of the JSON chunk and one binary chunk (glTF 2.0 section 4.4)."""
    chunk = json.dumps(document).encode()
    chunk += b" " * (-len(chunk) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(chunk) + 8 + len(binary)
    return (
        struct.pack("<4sII", b"glTF", 2, total)
        + struct.pack("<I4s", len(chunk), b"JSON")
        + chunk
        + struct.pack("<I4s", len(binary), b"BIN\0")
        + binary
    )


def textured_plate_glb(images: dict[str, bytes], node: dict | None = None) -> bytes:
    """A unit plate in z = 0 with normals, glTF texture coordinates (v down: the vertex
    at y = 1 has v = 0) and the given textures, one sampler (clamp along u, mirrored
    repeat along v)."""
    positions = PLATE_V.astype(np.float32)
    normals = np.array([[0, 0, 1], [0, 0, 1], [0.6, 0, 0.8], [0, 0, 1]], dtype=np.float32)
    texcoords = np.column_stack([positions[:, 0], 1.0 - positions[:, 1]]).astype(np.float32)
    indices = PLATE_F.astype(np.uint32).ravel()
    blobs = [positions.tobytes(), normals.tobytes(), texcoords.tobytes(), indices.tobytes()]
    blobs += list(images.values())
    views, offset = [], 0
    for blob in blobs:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(blob)})
        offset += len(blob) + (-len(blob) % 4)
    binary = b"".join(b + b"\0" * (-len(b) % 4) for b in blobs)
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
         "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 3, "componentType": 5125, "count": 6, "type": "SCALAR"},
    ]  # fmt: skip
    slots = list(images)
    material = {"name": "paint", "pbrMetallicRoughness": {"metallicFactor": 0.5}}
    for k, slot in enumerate(slots):
        info = {"index": k}
        if slot == "normalTexture":
            material["normalTexture"] = {**info, "scale": 0.7}
        else:
            material["pbrMetallicRoughness"][slot] = info
    document = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "plate", "mesh": 0, **(node or {})}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                        "indices": 3,
                        "material": 0,
                    }
                ]
            }
        ],
        "materials": [material],
        "samplers": [{"wrapS": 33071, "wrapT": 33648}],
        "images": [{"bufferView": 4 + k, "mimeType": "image/png"} for k in range(len(slots))],
        "textures": [{"source": k, "sampler": 0} for k in range(len(slots))],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    return glb(document, binary)


def test_glb_textures_normals_and_texture_coordinates_load(tmp_path: Path) -> None:
    base, mr, normal = test_pixels(3), test_pixels(4, (2, 2)), test_pixels(5, (8, 4))
    images = {
        "baseColorTexture": png_bytes(base),
        "metallicRoughnessTexture": png_bytes(mr),
        "normalTexture": png_bytes(normal),
    }
    path = tmp_path / "plate.glb"
    path.write_bytes(textured_plate_glb(images))
    mesh = load_mesh(path)
    textures = mesh.part_texture(0)
    np.testing.assert_array_equal(textures.base_color.pixels, base)
    np.testing.assert_array_equal(textures.metallic_roughness.pixels, mr)
    np.testing.assert_array_equal(textures.normal.pixels, normal)
    assert textures.base_color.encoding == "srgb"
    assert textures.metallic_roughness.encoding == textures.normal.encoding == "linear"
    assert textures.base_color.wrap_uv == ("clamp", "mirror")
    assert textures.normal_scale == pytest.approx(0.7)
    assert mesh.part_material(0).metallic == pytest.approx(0.5)
    # glTF's v runs down the image; satsight's up: v = 1 - v_glTF = y.
    positions = mesh.vertices_m[mesh.faces]
    np.testing.assert_allclose(mesh.corner_uv, positions[..., :2], atol=FLOAT32)
    # NORMAL per corner: (0.6, 0, 0.8) at (1, 1, 0), +z elsewhere.
    at_corner = np.all(np.isclose(positions, [1.0, 1.0, 0.0]), axis=-1)
    np.testing.assert_allclose(mesh.corner_normals[at_corner], [[0.6, 0, 0.8]] * 2, atol=FLOAT32)
    np.testing.assert_allclose(mesh.corner_normals[~at_corner], [[0, 0, 1.0]] * 4, atol=FLOAT32)


def test_glb_normals_follow_a_non_uniform_node_scale(tmp_path: Path) -> None:
    """Normals transform with the inverse transpose: stretching x by 2 halves the
    x-component of (0.6, 0, 0.8) before renormalising."""
    path = tmp_path / "plate.glb"
    path.write_bytes(textured_plate_glb({}, node={"scale": [2.0, 1.0, 1.0]}))
    mesh = load_mesh(path)
    positions = mesh.vertices_m[mesh.faces]
    at_corner = np.all(np.isclose(positions, [2.0, 1.0, 0.0]), axis=-1)
    want = np.array([0.3, 0.0, 0.8]) / np.hypot(0.3, 0.8)
    np.testing.assert_allclose(mesh.corner_normals[at_corner], [want] * 2, atol=FLOAT32)
    assert not mesh.textured
