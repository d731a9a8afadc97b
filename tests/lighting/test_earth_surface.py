"""The Earth's albedo map: land and sea where the GLOBE mask puts them, the mean albedo,
the cloud cover, determinism, and the renderer's texture lookup against the numpy twin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting import earth_surface
from satsight.lighting.earth_surface import (
    BOND_ALBEDO,
    EarthSurfaceModel,
    cloud_cover,
    cloud_noise,
    earth_albedo_map,
    land_fraction,
    map_mean_albedo,
)
from satsight.lighting.light_field import LightField
from satsight.lighting.scene_bodies import BACKGROUND_EARTH, earth_body
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts


def _cell(lat_deg: float, lon_deg: float) -> tuple[int, int]:
    return int((90.0 - lat_deg) / 0.1), int((lon_deg + 180.0) / 0.1)


def test_land_and_sea_where_the_map_of_the_world_has_them():
    land = land_fraction()
    assert land.shape == (1800, 3600)
    for lat, lon in [(40.0, -100.0), (0.0, 20.0), (-25.0, 135.0), (50.0, 90.0)]:  # land
        assert land[_cell(lat, lon)] == 1.0
    for lat, lon in [(0.0, -140.0), (-40.0, 0.0), (30.0, -40.0), (-20.0, 80.0)]:  # ocean
        assert land[_cell(lat, lon)] == 0.0
    lat = 90.0 - (np.arange(1800) + 0.5) * 0.1
    weights = np.cos(np.radians(lat))[:, None] * np.ones(3600)
    # The Earth's surface is 29 % land (NASA Earth Fact Sheet: 148.9 of 510.1 million km2).
    assert np.average(land, weights=weights) == pytest.approx(148.9 / 510.1, abs=0.01)


def test_the_land_fraction_is_read_once_and_cached_exactly(monkeypatch, tmp_path):
    """The 0.1 deg cells' ocean sample counts are cached (uint8, exact): a second call reads
    the cache, not the mask; a damaged cache file is rebuilt; the fraction is 1 - n / 144."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 145, size=(1800, 3600)).astype(np.uint8)
    reads = []
    monkeypatch.setattr(earth_surface, "_ocean_counts", lambda path: reads.append(path) or counts)
    first = land_fraction()
    assert len(reads) == 1
    np.testing.assert_array_equal(land_fraction(), first)
    assert len(reads) == 1
    assert first.dtype == np.float32
    # Two float32 roundings (n / 144, then 1 - it): within one float32 ulp of 1.
    np.testing.assert_allclose(first, 1.0 - counts / 144.0, rtol=0, atol=np.spacing(np.float32(1)))
    (cache_file,) = (tmp_path / "satsight").glob("globe_ocean_counts_*.npz")
    cache_file.write_bytes(b"not an npz")
    np.testing.assert_array_equal(land_fraction(), first)
    assert len(reads) == 2


def test_the_default_map_has_the_bond_albedo_and_the_cloud_fraction():
    albedo_map = earth_albedo_map()
    assert map_mean_albedo(albedo_map) == pytest.approx(BOND_ALBEDO, abs=1e-3)
    assert albedo_map.albedo_rgb.min() >= 0.0 and albedo_map.albedo_rgb.max() <= 1.0
    assert "GLOBE" in albedo_map.description


def test_cloud_cover_is_seeded_and_has_the_requested_mean(monkeypatch):
    # On a 1 deg grid, 100 times fewer cells than the map's 0.1 deg. What is checked does not
    # depend on the grid: the seed draws the same lattices whatever it is (their sizes follow
    # the octaves alone) and the grid only picks where they are read; the threshold search
    # makes the area mean exact on any cells (the ramp makes the mean cover continuous in
    # the threshold; 40 halvings leave ~1e-11 of it), so 1e-3 bounds the same error.
    monkeypatch.setattr(earth_surface, "MAP_ROWS", 180)
    monkeypatch.setattr(earth_surface, "MAP_COLS", 360)
    weights = np.cos(np.radians(90.0 - (np.arange(180) + 0.5) * 1.0))[:, None] * np.ones(360)
    a, b = cloud_noise(1), cloud_noise(1)
    assert a.shape == (180, 360)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, cloud_noise(2))
    for fraction in (0.2, 0.67):
        cover = cloud_cover(a, fraction, weights)
        assert np.average(cover, weights=weights) == pytest.approx(fraction, abs=1e-3)


def test_bad_surface_values_are_refused():
    from satsight.errors import SatsightError

    with pytest.raises(SatsightError, match="cloud_fraction"):
        EarthSurfaceModel(cloud_fraction=1.5)


def test_the_renderer_reads_the_map_as_the_numpy_twin_does():
    """The Earth seen from 20 000 km with the map: every Earth pixel's radiance equals the
    numpy model's along the same ray (bilinear texture vs bilinear lookup)."""
    v = np.array([[-0.1, -0.1, 0.0], [0.1, -0.1, 0.0], [0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    material = Material("plate", (0.5,) * 3, metallic=0.0, roughness=1.0, ior=1.0)
    mesh = merge_parts([("plate", "plate", v, f)], {"plate": material}, "plate")
    renderer = Renderer(mesh, RenderSettings(environment="off", bounces=0))
    sun = np.array([0.6, 0.3, 0.2]) / np.linalg.norm([0.6, 0.3, 0.2])
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # a turned Earth
    camera_body = np.array([100.0, 0.0, 0.0])
    center = -np.array([20_000e3 - 100.0, 0.0, 0.0])
    earth = earth_body(center, R, 0.3, sun, 1000.0, albedo_map=earth_albedo_map())
    camera = PinholeCamera(focal_length_m=0.05, pixel_pitch_m=15e-6, width_px=96, height_px=96)
    pose = look_at_cam_from_body(camera_body, center, up_hint_body=(0.0, 0.0, 1.0))
    image = renderer.render(camera, pose, LightField(sun, 1000.0, np.zeros((25, 3)), (earth,)))
    seen = image.background_mask() == BACKGROUND_EARTH
    assert seen.sum() > 1000
    y, x = np.nonzero(seen)
    f_px = camera.focal_length_px
    d_cam = np.stack([(x - camera.cx_px) / f_px, (y - camera.cy_px) / f_px, np.ones(x.size)], -1)
    d_body = d_cam @ pose.inverse().R_a_from_b.T
    d_body /= np.linalg.norm(d_body, axis=1, keepdims=True)
    expected = earth.radiance_along(camera_body, d_body)
    got = image.radiance_w_m2_sr[seen]
    assert expected.max() > 0.05 * 1000 / math.pi
    np.testing.assert_allclose(got, expected, rtol=2e-3, atol=1e-3 * expected.max())
