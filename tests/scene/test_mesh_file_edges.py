"""Mesh files at their edges: OBJ face indices (0, out of range, relative) and textures
that are missing, not images, or too large, in OBJ + MTL and glTF alike, with and without
``target.mesh.strict_textures``."""

from __future__ import annotations

import base64
import json
import logging
import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image
from tests.cli_runner import invoke_satsight, run_satsight
from tests.scene.test_surface_loading import png_bytes, test_pixels, textured_plate_glb

from satsight.config.target import MeshTargetConfig
from satsight.errors import SatsightError
from satsight.scene.loading import load_mesh
from satsight.scene.textures import MAX_TEXTURE_FILE_PIXELS, open_texture_file

LOGGER = "satsight.scene"  # the mesh file readers log under satsight.scene.*


def png_header(width: int, height: int) -> bytes:
    """A PNG that declares width x height RGB pixels but holds none (an empty IDAT):
    Pillow opens it and tells its size, and decoding it fails. A loader that reports the
    size read only the header."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", b"") + chunk(b"IEND", b"")


# --- OBJ face indices ------------------------------------------------------------------------
TRIANGLES = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"


@pytest.mark.parametrize(
    ("face", "message"),
    [
        ("f 0 1 2", "vertex index 0: OBJ indices start at 1"),
        ("f 1 2 4", "vertex index 4, but the file defines 3 vertices ('v' lines)"),
        ("f -4 -2 -1", "relative vertex index -4 reaches before the first vertex: only 3"),
        ("f 1/0 2/2 3/3", "texture coordinate index 0: OBJ indices start at 1"),
        ("f 1/1 2/2 3/7", "texture coordinate index 7, but the file defines 3 texture"),
        ("f 1/1/0 2/2/1 3/3/1", "normal index 0: OBJ indices start at 1"),
        ("f 1//2 2//1 3//1", "normal index 2, but the file defines 1 normals ('vn' lines)"),
        ("f 1 2 x", "'x' in corner 'x' is not an integer"),
    ],
)
def test_bad_face_indices_are_refused_with_the_line(tmp_path: Path, face: str, message: str):
    path = tmp_path / "bad.obj"
    path.write_text(TRIANGLES + "f 1 2 3\n" + face + "\n")
    with pytest.raises(SatsightError, match=re.escape(f"bad.obj, line 9 ('{face}'): ")) as caught:
        load_mesh(path)
    text = str(caught.value)
    assert text.startswith(f"bad.obj, line 9 ('{face}'): ")
    assert message in text


def test_zero_index_is_refused_even_where_every_other_index_is_valid(tmp_path: Path) -> None:
    # trimesh alone reads 'f 0 1 2' as 'f 1 1 2' (a degenerate triangle) without a word.
    path = tmp_path / "zero.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 2 3 4\nf 0 1 2\n")
    with pytest.raises(SatsightError, match=r"zero.obj, line 6 \('f 0 1 2'\): vertex index 0"):
        load_mesh(path)


def test_relative_indices_count_back_from_their_own_line(tmp_path: Path) -> None:
    """-1 is the latest element defined above the face (OBJ), not the file's last one:
    the file reads the same as its copy with absolute indices."""
    first, second = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[5, 0, 0], [6, 0, 0], [5, 1, 0]]
    uv_first, uv_second = [[0, 0], [1, 0], [0, 1]], [[0.5, 0.5], [1, 0.5], [0.5, 1]]

    def block(points, uvs, corners):
        lines = [f"v {x} {y} {z}" for x, y, z in points] + [f"vt {u} {v}" for u, v in uvs]
        return "\n".join(lines) + f"\nf {corners}\n"

    relative = block(first, uv_first, "-3/-3 -2/-2 -1/-1")
    relative += "# a comment line\n" + block(second, uv_second, "-3/-3 -2/-2 -1/-1 # second")
    absolute = block(first, uv_first, "1/1 2/2 3/3") + block(second, uv_second, "4/4 5/5 6/6")
    (tmp_path / "relative.obj").write_text(relative)
    (tmp_path / "absolute.obj").write_text(absolute)
    got, want = load_mesh(tmp_path / "relative.obj"), load_mesh(tmp_path / "absolute.obj")
    corners = got.vertices_m[got.faces]
    np.testing.assert_array_equal(corners, want.vertices_m[want.faces])
    np.testing.assert_array_equal(got.corner_uv, want.corner_uv)
    # Both triangles are there, each with its own three vertices.
    assert {tuple(map(tuple, tri)) for tri in corners.tolist()} == {
        tuple(map(tuple, first)),
        tuple(map(tuple, second)),
    }


def test_relative_indices_keep_the_material_library_and_its_texture(tmp_path: Path) -> None:
    """A file with relative indices is read from memory; its MTL and map_Kd still resolve
    beside it, and the parts keep the file's name."""
    pixels = test_pixels(7)
    Image.fromarray(pixels).save(tmp_path / "paint.png")
    (tmp_path / "plate.mtl").write_text("newmtl paint\nKd 1 1 1\nmap_Kd paint.png\n")
    text = "mtllib plate.mtl\n" + TRIANGLES + "usemtl paint\nf -3/-3/-1 -2/-2/-1 -1/-1/-1\n"
    (tmp_path / "plate.obj").write_text(text)
    mesh = load_mesh(tmp_path / "plate.obj")
    assert tuple(mesh.part_names) == ("plate",)
    np.testing.assert_array_equal(mesh.part_texture(0).base_color.pixels, pixels)


def test_large_valid_obj_takes_the_fast_path_and_loads(tmp_path: Path) -> None:
    n = 60
    u, v = np.meshgrid(np.arange(n), np.arange(n))
    grid = np.arange(n * n).reshape(n, n) + 1
    a, b, c, d = grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]
    faces = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]]
    lines = [f"v {x} {y} 0" for x, y in zip(u.ravel(), v.ravel(), strict=True)]
    lines += ["vn 0 0 1"] + [f"f {i}//1 {j}//1 {k}//1" for i, j, k in faces]
    (tmp_path / "grid.obj").write_text("\n".join(lines) + "\n")
    mesh = load_mesh(tmp_path / "grid.obj")
    assert len(mesh.faces) == len(faces)
    # One bad index at the very end of the same file is still found, with its line.
    (tmp_path / "grid.obj").write_text("\n".join(lines) + f"\nf 1//1 2//1 {n * n + 1}//1\n")
    with pytest.raises(SatsightError, match=rf"line {len(lines) + 1} .*vertex index {n * n + 1}"):
        load_mesh(tmp_path / "grid.obj")


# --- texture files ---------------------------------------------------------------------------
BAD_TEXTURES = {
    "missing": (None, "does not exist"),
    "text": (b"this is a note, not an image\n", "is not an image Pillow can read"),
    "huge": (png_header(40000, 40000), "1,600,000,000 px, more than the 134,217,728 px"),
    "over_the_limit": (png_header(16384, 8193), "is 16384 x 8193 px, more than the"),
}


def test_texture_limit_is_stated_and_headers_are_read_without_decoding() -> None:
    assert MAX_TEXTURE_FILE_PIXELS == 2**27
    image, problem = open_texture_file(png_header(16384, 8192))  # at the limit: accepted
    assert problem is None and image.size == (16384, 8192)
    image, problem = open_texture_file(png_header(16384, 8193))
    assert image is None and "16384 x 8193 px" in problem


def write_textured_obj(folder: Path, texture: bytes | None, line: str = "map_Kd paint.png"):
    if texture is not None:
        (folder / "paint.png").write_bytes(texture)
    (folder / "plate.mtl").write_text(f"newmtl paint\nKd 0.5 0.5 0.5\n{line}\n")
    text = "mtllib plate.mtl\n" + TRIANGLES + "usemtl paint\nf 1/1/1 2/2/1 3/3/1\n"
    (folder / "plate.obj").write_text(text)
    return folder / "plate.obj"


@pytest.mark.parametrize("case", sorted(BAD_TEXTURES))
def test_obj_bad_texture_warns_and_renders_untextured(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, case: str
) -> None:
    data, reason = BAD_TEXTURES[case]
    path = write_textured_obj(tmp_path, data)
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        mesh = load_mesh(path)
    assert mesh.part_texture(0) is None
    assert mesh.part_material(0).base_color_rgb == (0.5, 0.5, 0.5)  # the rest of the material
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    mine = [w for w in warnings if "map_Kd 'paint.png'" in w]
    assert len(mine) == 1, warnings
    assert mine[0].startswith("plate.obj: material 'paint': texture map_Kd 'paint.png' ")
    assert "(plate.mtl line 3)" in mine[0] and reason in mine[0]
    assert "target.mesh.strict_textures: true makes this an error" in mine[0]


@pytest.mark.parametrize("case", sorted(BAD_TEXTURES))
def test_obj_bad_texture_is_an_error_when_strict(tmp_path: Path, case: str) -> None:
    data, reason = BAD_TEXTURES[case]
    path = write_textured_obj(tmp_path, data)
    with pytest.raises(SatsightError, match=r"target\.mesh\.strict_textures is true") as caught:
        load_mesh(path, strict_textures=True)
    text = str(caught.value)
    assert text.startswith("plate.obj: material 'paint': texture map_Kd 'paint.png' ")
    assert reason in text and "target.mesh.strict_textures is true" in text


def test_obj_good_texture_loads_when_strict_and_map_options_are_named(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    pixels = test_pixels(2)
    path = write_textured_obj(tmp_path, png_bytes(pixels), "map_Kd -s 2 2 1 -bm 0.5 paint.png")
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        mesh = load_mesh(path, strict_textures=True)
    np.testing.assert_array_equal(mesh.part_texture(0).base_color.pixels, pixels)
    assert "plate.mtl, line 3: map_Kd options not applied: -s 2 2 1, -bm 0.5" in caplog.text


GLTF_BAD_IMAGES = {
    "text": (b"this is a note, not an image\n", "is not an image Pillow can read"),
    "huge": (png_header(40000, 40000), "1,600,000,000 px, more than the 134,217,728 px"),
    "over_the_limit": (png_header(16384, 8193), "is 16384 x 8193 px, more than the"),
}


@pytest.mark.parametrize("case", sorted(GLTF_BAD_IMAGES))
def test_glb_bad_embedded_texture_warns_like_obj(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, case: str
) -> None:
    data, reason = GLTF_BAD_IMAGES[case]
    normal = png_bytes(test_pixels(5, (4, 4)))
    path = tmp_path / "plate.glb"
    path.write_bytes(textured_plate_glb({"baseColorTexture": data, "normalTexture": normal}))
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        mesh = load_mesh(path)
    textures = mesh.part_texture(0)
    assert textures.base_color is None and textures.normal is not None  # the good one stays
    mine = [r.getMessage() for r in caplog.records if "baseColorTexture" in r.getMessage()]
    assert len(mine) == 1
    assert mine[0].startswith(
        "plate.glb: material 'paint': texture baseColorTexture (image 0, embedded) "
    )
    assert reason in mine[0] and "strict_textures: true makes this an error" in mine[0]
    with pytest.raises(SatsightError, match="material 'paint': texture baseColorTexture") as e:
        load_mesh(path, strict_textures=True)
    assert reason in str(e.value)


def gltf_with_image_uri(folder: Path, uri: str) -> Path:
    """The textured plate as a .gltf whose buffer is a data URI and whose base-colour image
    is the file ``uri`` beside it."""
    blob = textured_plate_glb({"baseColorTexture": png_bytes(test_pixels(1))})
    json_length = struct.unpack_from("<I", blob, 12)[0]
    document = json.loads(blob[20 : 20 + json_length])
    binary = blob[20 + json_length + 8 :]
    encoded = base64.b64encode(binary).decode()
    document["buffers"] = [
        {"byteLength": len(binary), "uri": "data:application/octet-stream;base64," + encoded}
    ]
    document["images"] = [{"uri": uri}]
    path = folder / "plate.gltf"
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize("case", ["missing", "text", "huge"])
def test_gltf_bad_texture_file_warns_or_fails(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, case: str
) -> None:
    data, reason = BAD_TEXTURES[case]
    if data is not None:
        (tmp_path / "paint.png").write_bytes(data)
    path = gltf_with_image_uri(tmp_path, "paint.png")
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        mesh = load_mesh(path)
    assert mesh.part_texture(0) is None
    assert "plate.gltf: material 'paint': texture baseColorTexture ('paint.png') " in caplog.text
    assert reason in caplog.text
    with pytest.raises(SatsightError, match=r"baseColorTexture \('paint.png'\)"):
        load_mesh(path, strict_textures=True)


def test_gltf_good_texture_file_loads(tmp_path: Path) -> None:
    pixels = test_pixels(9)
    Image.fromarray(pixels).save(tmp_path / "paint.png")
    mesh = load_mesh(gltf_with_image_uri(tmp_path, "paint.png"), strict_textures=True)
    np.testing.assert_array_equal(mesh.part_texture(0).base_color.pixels, pixels)


# --- scenario key and command line -----------------------------------------------------------
def test_scenario_key_strict_textures() -> None:
    assert MeshTargetConfig(path="x.obj").strict_textures is False
    assert MeshTargetConfig(path="x.obj", strict_textures=True).strict_textures is True
    with pytest.raises(ValueError, match="strict_textures"):
        MeshTargetConfig(path="x.obj", strict_textures="sometimes")


def scenario_file(folder: Path, mesh: Path, strict: bool = False) -> Path:
    scenario = {
        "name": "mesh-edges",
        "camera": {"preset": "wide_field", "width_px": 48, "height_px": 40},
        "target": {"mesh": {"path": mesh.name, "strict_textures": strict}},
        "frames": [{"distance_km": 0.05, "azimuth_deg": 10.0, "elevation_deg": 60.0}],
        "render": {"bounces": 0},
    }
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario))
    return path


def assert_refused(result, *phrases: str) -> None:
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    for phrase in phrases:
        assert phrase in " ".join((result.stdout + result.stderr).split())


def test_cli_refuses_index_zero_with_the_line(tmp_path: Path) -> None:
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    config = scenario_file(tmp_path, tmp_path / "zero.obj")
    result = invoke_satsight("generate", str(config), "--out", "ds", cwd=tmp_path)
    assert_refused(result, "zero.obj, line 4 ('f 0 1 2'): vertex index 0")
    assert not list((tmp_path / "ds").glob("**/*.png"))


def test_cli_strict_textures_refuses_and_default_warns_and_renders(tmp_path: Path) -> None:
    path = write_textured_obj(tmp_path, BAD_TEXTURES["huge"][0])
    strict = run_satsight(
        "generate", str(scenario_file(tmp_path, path, True)), "--out", "strict", cwd=tmp_path
    )
    assert_refused(strict, "material 'paint': texture map_Kd 'paint.png'", "1,600,000,000 px")
    assert not list((tmp_path / "strict").glob("**/*.png"))
    lenient = run_satsight(
        "generate", str(scenario_file(tmp_path, path)), "--out", "lenient", cwd=tmp_path
    )
    output = " ".join((lenient.stdout + lenient.stderr).split())
    assert lenient.returncode == 0, output
    assert "material 'paint': texture map_Kd 'paint.png' (plate.mtl line 3) holds" in output
    assert "the material is rendered without it" in output
    assert (tmp_path / "lenient" / "complete.json").is_file()
