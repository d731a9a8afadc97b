"""The SH field of the Earth as the renderer traces it (ellipsoid, albedo map, orientation).

``scene_body_sh`` projects ``SceneBody.radiance_along`` with a Gauss-Legendre product
quadrature over the cone of the body's bounding sphere. The oracle here is an independent
projection: a Fibonacci lattice over the same spherical cap (mu uniform in [cos alpha, 1],
golden-angle azimuths), equal solid-angle weights, the same radiance function. Measured
against a 512-node projection, the lattice with 2^20 points is within 1.2e-4 of c_00 and the
128-node default within 4e-4 (the ellipsoid's limb inside the cone and the map's edges are
what limits both); the tolerance, 1e-3 of c_00, holds both with room.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.constants import EARTH_MEAN_RADIUS_M, WGS84_SEMI_MAJOR_AXIS_M
from satsight.errors import SatsightError
from satsight.lighting import sh
from satsight.lighting.bodies import (
    DEFAULT_SH_NODES,
    body_sh,
    environment_light_field,
    scene_body_sh,
)
from satsight.lighting.scene_bodies import AlbedoMap, earth_body

E_SUN_W_M2 = 1000.0
L_MAX = 4


def _fibonacci_cap(axis: np.ndarray, cos_alpha: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """n directions of a Fibonacci lattice on the cap of half-angle alpha about ``axis``,
    and their equal solid-angle weights 2 pi (1 - cos alpha) / n."""
    k = np.arange(n) + 0.5
    mu = 1.0 - (1.0 - cos_alpha) * k / n
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    a = axis / np.linalg.norm(axis)
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    dirs = mu[:, None] * a + np.sqrt(1.0 - mu * mu)[:, None] * radial
    return dirs, np.full(n, 2.0 * math.pi * (1.0 - cos_alpha) / n)


def _rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * K + (1 - math.cos(angle_rad)) * K @ K


def _patchy_map() -> AlbedoMap:
    """Continents of 0.25 on a 0.06 ocean, polar caps of 0.8: sharp edges, as the real map."""
    rows, cols = 180, 360
    lat = 90.0 - (np.arange(rows) + 0.5) * 180.0 / rows
    lon = -180.0 + (np.arange(cols) + 0.5) * 360.0 / cols
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    albedo = np.full((rows, cols), 0.06)
    albedo[(np.abs(la - 20) < 30) & (np.abs(lo + 60) < 40)] = 0.25
    albedo[(np.abs(la + 10) < 25) & (np.abs(lo - 70) < 50)] = 0.25
    albedo[np.abs(la) > 70] = 0.8
    return AlbedoMap(np.repeat(albedo[:, :, None], 3, axis=2).astype(np.float32), "test")


@pytest.mark.parametrize(
    "altitude_m, sun",
    [(500e3, (0.3, 0.2, 0.93)), (500e3, (1.0, 0.0, 0.1)), (35_786e3, (0.2, -0.5, 0.8))],
    ids=["leo-day", "leo-terminator", "geo"],
)
def test_textured_ellipsoid_projection_matches_a_whole_sphere_lattice(altitude_m, sun) -> None:
    center = np.array([0.1, -0.2, -1.0])
    center *= (WGS84_SEMI_MAJOR_AXIS_M + altitude_m) / np.linalg.norm(center)
    body = earth_body(
        center,
        _rotation(np.array([0.3, 1.0, 0.2]), 0.7),
        0.3,
        np.array(sun),
        E_SUN_W_M2,
        albedo_map=_patchy_map(),
        shape="wgs84",
    )
    coeffs = scene_body_sh(body, l_max=L_MAX)
    d = np.linalg.norm(center)
    cos_alpha = math.sqrt(d * d - WGS84_SEMI_MAJOR_AXIS_M**2) / d
    dirs, weights = _fibonacci_cap(center, cos_alpha, 1 << 20)
    reference = sh.project_samples(dirs, body.radiance_along(np.zeros(3), dirs), weights, L_MAX)
    scale = abs(reference[0, 0])
    assert scale > 0
    np.testing.assert_allclose(coeffs, reference, rtol=0, atol=1e-3 * scale)


def test_a_uniform_sphere_gives_the_sphere_projection() -> None:
    """With no map and a spherical shape the body is the uniform sphere of ``body_sh``: the
    same quadrature nodes give the same coefficients (terminator across the disc). The
    sphere's default radius is the mean radius R1."""
    center = np.array([0.0, 0.0, -(EARTH_MEAN_RADIUS_M + 700e3)])
    sun = np.array([0.95, 0.0, 0.3])
    body = earth_body(center, np.eye(3), 0.3, sun, E_SUN_W_M2, shape="sphere")
    np.testing.assert_allclose(
        scene_body_sh(body, l_max=6, n_nodes=DEFAULT_SH_NODES),
        body_sh(center, EARTH_MEAN_RADIUS_M, sun, 0.3, E_SUN_W_M2, l_max=6),
        rtol=0,
        atol=1e-12 * E_SUN_W_M2,
    )


def test_the_light_field_takes_the_scene_earth_when_given() -> None:
    center = np.array([0.0, 0.0, -(WGS84_SEMI_MAJOR_AXIS_M + 700e3)])
    sun = np.array([0.6, 0.0, 0.8])
    body = earth_body(center, np.eye(3), 0.3, sun, E_SUN_W_M2, albedo_map=_patchy_map())
    field = environment_light_field(
        sun, E_SUN_W_M2, earth_center_from_target_m=center, earth=body, l_max=L_MAX
    )
    np.testing.assert_array_equal(field.sh_radiance_w_m2_sr, scene_body_sh(body, l_max=L_MAX))
    uniform = environment_light_field(sun, E_SUN_W_M2, earth_center_from_target_m=center)
    assert not np.allclose(field.sh_radiance_w_m2_sr, uniform.sh_radiance_w_m2_sr, rtol=1e-2)


def test_a_grey_map_is_its_three_channel_copy() -> None:
    """A grey map (rows, cols, 1) looks up, and projects onto SH, as the same map repeated
    in three channels; other channel counts are refused."""
    rgb = _patchy_map()
    grey = AlbedoMap(rgb.albedo_rgb[..., :1], "grey")
    rng = np.random.default_rng(2)
    lat, lon = rng.uniform(-1.6, 1.6, 500), rng.uniform(-3.2, 3.2, 500)
    looked_up = grey.lookup(lat, lon)
    assert looked_up.shape == (500, 3)
    np.testing.assert_array_equal(looked_up, rgb.lookup(lat, lon))
    center = (
        np.array([0.1, -0.2, -1.0]) * (WGS84_SEMI_MAJOR_AXIS_M + 500e3) / math.hypot(0.1, 0.2, 1.0)
    )
    sun = np.array([0.3, 0.2, 0.93])
    bodies = [
        earth_body(center, np.eye(3), 0.3, sun, E_SUN_W_M2, albedo_map=m) for m in (grey, rgb)
    ]
    np.testing.assert_array_equal(
        scene_body_sh(bodies[0], l_max=4), scene_body_sh(bodies[1], l_max=4)
    )
    with pytest.raises(SatsightError, match=r"\(rows, cols, 3\) or \(rows, cols, 1\)"):
        AlbedoMap(np.zeros((4, 8, 2), np.float32))
