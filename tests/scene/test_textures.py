"""Texture images and the procedural satellites' textures (cells, MLI crinkle, radiators)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.scene import procedural_textures as pt
from satsight.scene.materials import FIRST_MATERIALS
from satsight.scene.procedural import SATELLITE_CLASSES, generate_satellite
from satsight.scene.textures import (
    SurfaceTextures,
    TextureImage,
    decode,
    encode,
    halve,
    linear_to_srgb,
    srgb_to_linear,
)

CODE_STEP = 1.0 / 255.0


def test_srgb_transfer_function_round_trips_and_matches_iec_61966_2_1() -> None:
    x = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)
    # Reference points: the linear segment below 0.04045 and 0.5 -> 0.21404.
    assert srgb_to_linear(0.04) == pytest.approx(0.04 / 12.92)
    assert srgb_to_linear(0.5) == pytest.approx(0.214041, abs=1e-6)
    codes = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(encode(decode(codes, "srgb"), "srgb"), codes)


def test_halving_averages_in_linear_light() -> None:
    black_white = np.zeros((2, 2, 3), dtype=np.uint8)
    black_white[0, 0] = black_white[1, 1] = 255
    half = halve(black_white, "srgb")
    assert half.shape == (1, 1, 3)
    # Mean linear value 0.5 is sRGB code 188, not the code mean 128.
    assert decode(half, "srgb")[0, 0, 0] == pytest.approx(0.5, abs=0.003)
    assert halve(black_white, "linear")[0, 0, 0] in (127, 128)


def test_texture_image_validates_its_input() -> None:
    with pytest.raises(SatsightError, match="uint8"):
        TextureImage(np.zeros((2, 2, 3), dtype=np.float32))
    with pytest.raises(SatsightError, match="wrap modes"):
        TextureImage(np.zeros((2, 2, 3), dtype=np.uint8), wrap_uv=("repeat", "tile"))
    grey = TextureImage(np.full((3, 5), 7, dtype=np.uint8), "linear")
    assert grey.pixels.shape == (3, 5, 3) and grey.size_px == (5, 3)
    with pytest.raises(SatsightError, match="sRGB"):
        SurfaceTextures(base_color=grey)


def test_cell_tile_holds_the_area_fractions_of_cell_gap_and_silver() -> None:
    """Each texel averages the materials over its area, so the tile's mean metallic value
    is the silver's area fraction (busbar plus fingers), and its mean base colour the
    area-weighted mean, to 8-bit precision."""
    pu, pv = 0.08, 0.04
    tile = pt.solar_cell_textures((pu, pv))
    gap, bus = pt.CELL_GAP_M, pt.BUSBAR_WIDTH_M
    inner_u, inner_v = pu - gap, pv - gap
    fingers = inner_u / pt.FINGER_PITCH_M * pt.FINGER_WIDTH_M  # their width along u
    silver = (bus * inner_u + fingers * (inner_v - bus)) / (pu * pv)
    cell = (inner_u - fingers) * (inner_v - bus) / (pu * pv)
    substrate = 1.0 - silver - cell
    metallic = decode(tile.metallic_roughness.pixels, "linear")[..., 2]
    assert metallic.mean() == pytest.approx(silver, abs=0.01)
    base = decode(tile.base_color.pixels, "srgb").mean(axis=(0, 1))
    want = (
        cell * np.array(FIRST_MATERIALS["solar_cell"].base_color_rgb)
        + silver * np.array([0.90, 0.90, 0.88])
        + substrate * np.array(FIRST_MATERIALS["panel_substrate"].base_color_rgb)
    )
    np.testing.assert_allclose(base, want, rtol=0.03)
    assert tile.factors == "replace"


def test_mli_crinkle_is_seeded_periodic_and_has_the_stated_tilt() -> None:
    a = pt.mli_crinkle_textures(np.random.default_rng([4, 1])).normal.pixels
    b = pt.mli_crinkle_textures(np.random.default_rng([4, 1])).normal.pixels
    c = pt.mli_crinkle_textures(np.random.default_rng([5, 1])).normal.pixels
    np.testing.assert_array_equal(a, b)
    assert np.mean(a != c) > 0.5
    n = 2.0 * decode(a, "linear") - 1.0
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    slope = np.hypot(n[..., 0], n[..., 1]) / n[..., 2]
    rms_tilt = math.degrees(math.atan(np.sqrt(np.mean(slope**2))))
    assert rms_tilt == pytest.approx(pt.MLI_RMS_TILT_DEG, abs=1.0)
    # Periodic: the wrap-around step is no larger than the steps inside the tile.
    inner = np.abs(np.diff(n, axis=1)).mean()
    seam = np.abs(n[:, 0] - n[:, -1]).mean()
    assert seam < 1.5 * inner


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_surfaces_keep_the_geometry_of_the_seed_and_are_deterministic(satellite_class) -> None:
    bare = generate_satellite(satellite_class, 7)
    rich = generate_satellite(satellite_class, 7, smooth_normals=True, textures=True)
    again = generate_satellite(satellite_class, 7, smooth_normals=True, textures=True)
    assert not bare.smooth and not bare.textured
    np.testing.assert_array_equal(rich.vertices_m, bare.vertices_m)
    np.testing.assert_array_equal(rich.faces, bare.faces)
    assert rich.part_materials == bare.part_materials
    assert rich.smooth and rich.textured
    np.testing.assert_array_equal(rich.corner_normals, again.corner_normals)
    np.testing.assert_array_equal(rich.corner_uv, again.corner_uv)
    for t1, t2 in zip(rich.part_textures, again.part_textures, strict=True):
        assert (t1 is None) == (t2 is None)
        if t1 is not None and t1.normal is not None:
            np.testing.assert_array_equal(t1.normal.pixels, t2.normal.pixels)
    textured = {n for n, t in zip(rich.part_names, rich.part_textures, strict=True) if t}
    assert "bus_mli" in textured and "radiator_1" in textured
    assert any("cells" in n for n in textured)


def test_cells_fill_each_panel_with_whole_cells() -> None:
    mesh = generate_satellite("two_wings", 2, textures=True)
    index = mesh.part_names.index("wing_1_cells")
    faces = mesh.faces[mesh.face_part_index == index]
    tri = mesh.vertices_m[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    front = np.abs(cross @ (cross[np.argmax(np.linalg.norm(cross, axis=1))])) > 0  # cell side
    front &= np.linalg.norm(cross, axis=1) > 0.5 * np.linalg.norm(cross, axis=1).max()
    uv = mesh.corner_uv[mesh.face_part_index == index][front]
    # The cell face's texture coordinates run over whole tiles: from 0 to an integer.
    for axis in range(2):
        top = uv[..., axis].max()
        assert uv[..., axis].min() == pytest.approx(0.0, abs=1e-9)
        assert top == pytest.approx(round(top), abs=1e-9) and top >= 10


def test_dish_is_smooth_and_boxes_stay_flat() -> None:
    mesh = generate_satellite("two_wings_dish", 1, smooth_normals=True)
    fn = np.cross(
        mesh.vertices_m[mesh.faces[:, 1]] - mesh.vertices_m[mesh.faces[:, 0]],
        mesh.vertices_m[mesh.faces[:, 2]] - mesh.vertices_m[mesh.faces[:, 0]],
    )
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    bent = np.abs(np.einsum("fkj,fj->fk", mesh.corner_normals, fn)).min(axis=1) < 1 - 1e-9
    dish = mesh.face_part_index == mesh.part_names.index("antenna_dish")
    bus = mesh.face_part_index == mesh.part_names.index("bus_mli")
    assert bent[dish].mean() > 0.9  # the paraboloid's faces (not its thin rim)
    assert not bent[bus].any()


def test_reseeding_remakes_the_crinkle_alone_from_its_own_seed() -> None:
    """``reseeded``: the MLI parts' normal maps are drawn again (other wrinkles, the same
    stated tilt, the same seed giving the same bytes); every other part keeps its
    textures (the same objects)."""
    mesh = generate_satellite("two_wings_dish", seed=3, textures=True)
    parts = pt.reseedable_parts(mesh)
    assert [mesh.part_names[k] for k in parts] == ["bus_mli"]
    a, b, c = pt.reseeded(mesh, 7), pt.reseeded(mesh, 7), pt.reseeded(mesh, 8)
    (k,) = parts
    old, new = mesh.part_textures[k].normal.pixels, a.part_textures[k].normal.pixels
    assert old.shape == new.shape and not np.array_equal(old, new)
    assert np.array_equal(new, b.part_textures[k].normal.pixels)
    assert not np.array_equal(new, c.part_textures[k].normal.pixels)
    assert a.part_textures[k].procedural == "mli_crinkle"
    for j, textures in enumerate(mesh.part_textures):
        if j != k:
            assert a.part_textures[j] is textures
    assert pt.reseeded(mesh, 7, parts=[]) is mesh

    n = 2.0 * decode(new, "linear") - 1.0
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    slope = np.hypot(n[..., 0], n[..., 1]) / n[..., 2]
    rms_tilt = math.degrees(math.atan(np.sqrt(np.mean(slope**2))))
    assert rms_tilt == pytest.approx(pt.MLI_RMS_TILT_DEG, abs=1.0)
