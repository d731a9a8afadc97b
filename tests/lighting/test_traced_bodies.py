"""The spherical Earth of a scenario and the Moon as traced bodies, against closed forms.

* ``earth.shape: sphere`` is the mean sphere R1 = 6 371 008.8 m with the target
  ``altitude_km`` above it: the limb in a rendered frame lies on the tangent cone of
  half-angle asin(R1 / d), d = R1 + h (projected here with the pinhole model, to 1 px), and
  the earthshine on a plate facing the Earth at full phase is the closed form of a Lambert
  sphere (the sub-solar plate, derived in ``test_bodies.py``) with R1 and d.
* The Moon: its pixels carry background id 2 and the Lambert radiance rho E cos / pi of the
  point each pixel-centre ray meets (an independent ray-sphere intersection), and the
  moonshine on a plate facing the full Moon is the same closed form with the Moon's radius,
  distance and albedo.

A wrong sphere radius (WGS-84 a instead of R1) moves the limb by 28 px in the frame below
and raises the facing-plate earthshine by 0.24 %; both are many times the tolerances.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.config.lighting import EarthConfig
from satsight.constants import EARTH_MEAN_RADIUS_M, MOON_ALBEDO, MOON_MEAN_RADIUS_M
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.lighting.scene_bodies import (
    BACKGROUND_EARTH,
    BACKGROUND_MOON,
    BACKGROUND_SPACE,
    earth_body,
    moon_body,
)
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts

E_SUN_W_M2 = 1000.0
PLATE_RHO = 0.5
ALTITUDE_KM = 500.0
MOON_DISTANCE_M = 384_400e3


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def subsolar_plate_irradiance(rho: float, e_sun: float, radius_m: float, d_m: float) -> float:
    """Irradiance on a plate facing the centre of a Lambert sphere (radius R, albedo rho)
    from distance d, with the Sun behind the plate (full phase):
    rho E [a (1 + a^2) / 2 + (1 - a)^2 / 4 - (1 - a^2)^2 artanh(a) / (4 a)], a = R / d
    (derivation in tests/lighting/test_bodies.py; far field (2/3) rho E a^2)."""
    a = radius_m / d_m
    return (
        rho
        * e_sun
        * (a * (1 + a * a) / 2 + (1 - a) ** 2 / 4 - (1 - a * a) ** 2 * math.atanh(a) / (4 * a))
    )


def axisymmetric_plate_irradiance(body, axis: np.ndarray, max_angle_rad: float, n: int) -> float:
    """E = 2 pi integral_0^max L(theta) cos(theta) sin(theta) d theta on a plate at the
    origin facing ``axis``, for a radiance symmetric about that axis (full phase): the
    body's traced radiance sampled along one meridian, midpoint rule with n nodes. The
    limb is a jump inside [0, max], so the error is O(L dtheta sin(alpha)) / E ~ 1 / n."""
    e1 = _unit(np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]))
    theta = (np.arange(n) + 0.5) * (max_angle_rad / n)
    dirs = np.cos(theta)[:, None] * axis + np.sin(theta)[:, None] * e1
    radiance = body.radiance_along(np.zeros(3), dirs)[:, 1]
    return float(
        2.0 * math.pi * np.sum(radiance * np.cos(theta) * np.sin(theta)) * (max_angle_rad / n)
    )


@pytest.fixture(scope="module")
def renderer():
    v, f = plate_parts(size_m=0.2)
    material = Material("plate_lambert", (PLATE_RHO,) * 3, metallic=0.0, roughness=1.0, ior=1.0)
    mesh = merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")
    settings = RenderSettings(environment="sampled", bounces=0, samples_per_pixel=256)
    return Renderer(mesh, settings)


def _scenario_earth(sun_body: np.ndarray):
    """The Earth of a scenario with ``shape: sphere`` straight below the target (body -z),
    as the pipeline builds it: centre from the config, the body from ``earth_body``."""
    config = EarthConfig(
        elevation_deg=-90.0, altitude_km=ALTITUDE_KM, shape="sphere", surface="uniform"
    )
    center = config.center_from_target_m()
    body = earth_body(center, np.eye(3), config.albedo, sun_body, E_SUN_W_M2, shape=config.shape)
    return config, body


def test_the_sphere_earth_limb_lies_on_the_mean_sphere_tangent_cone(renderer):
    _, earth = _scenario_earth(_unit([0.2, 0.1, 1.0]))
    d = EARTH_MEAN_RADIUS_M + ALTITUDE_KM * 1e3  # what the scenario says
    center = np.array([0.0, 0.0, -d])
    # A 256-px row across the limb, 1e-4 rad a pixel (28 px per 7.1 km of radius), from a
    # camera 5 m beside the plate, looking along the tangent cone of the mean sphere.
    camera_body = np.array([0.0, 5.0, 0.0])
    axis = center - camera_body
    distance = float(np.linalg.norm(axis))
    alpha = math.asin(EARTH_MEAN_RADIUS_M / distance)
    limb_dir = _unit(math.cos(alpha) * _unit(axis) + math.sin(alpha) * np.array([1.0, 0, 0]))
    camera = PinholeCamera(
        focal_length_m=0.15, pixel_pitch_m=15e-6, width_px=256, height_px=1, cy_px=0.0
    )
    pose = look_at_cam_from_body(camera_body, camera_body + limb_dir, up_hint_body=(0, 1, 0))
    light = LightField(earth.sun_direction_body, E_SUN_W_M2, np.zeros((25, 3)), bodies=(earth,))
    row = renderer.render(camera, pose, light, seed=3).background_mask()[0]
    assert set(np.unique(row)) == {BACKGROUND_SPACE, BACKGROUND_EARTH}
    changes = np.flatnonzero(np.diff(row.astype(int)) != 0)
    assert changes.size == 1  # one limb crossing
    measured_edge_px = changes[0] + 0.5

    # The pinhole model by hand: pixel u looks along R_body_from_cam ((u - cx) / f, 0, 1);
    # the edge is where that ray makes the angle alpha with the axis.
    R_body_from_cam = pose.R_a_from_b.T
    f_px = 0.15 / 15e-6
    cx = (camera.width_px - 1) / 2.0

    def angle_minus_alpha(u: float) -> float:
        ray = R_body_from_cam @ np.array([(u - cx) / f_px, 0.0, 1.0])
        cos = float(_unit(ray) @ _unit(axis))
        return math.acos(min(1.0, cos)) - alpha

    expected_edge_px = brentq(angle_minus_alpha, -0.5, camera.width_px - 0.5, xtol=1e-9)
    assert abs(expected_edge_px - cx) < 1.0  # the boresight is on the limb
    assert abs(measured_edge_px - expected_edge_px) <= 1.0
    assert row[0] != row[-1]


def test_the_sphere_earth_earthshine_on_a_facing_plate_is_the_mean_sphere_closed_form():
    # The Sun straight behind the plate (body +z), the Earth below it: full phase.
    config, earth = _scenario_earth(np.array([0.0, 0.0, 1.0]))
    d = EARTH_MEAN_RADIUS_M + ALTITUDE_KM * 1e3
    expected = subsolar_plate_irradiance(config.albedo, E_SUN_W_M2, EARTH_MEAN_RADIUS_M, d)
    # Integrate out to 2 deg beyond the mean sphere's limb, so a larger sphere would count.
    max_angle = math.asin(EARTH_MEAN_RADIUS_M / d) + math.radians(2.0)
    got = axisymmetric_plate_irradiance(earth, np.array([0.0, 0.0, -1.0]), max_angle, 200_000)
    # Budget: the midpoint rule across the limb's jump, L dtheta / 2 over E, < 1e-5.
    assert got == pytest.approx(expected, rel=1e-4)


def _moon_view(sun: np.ndarray):
    """The Moon (mean radius, albedo 0.12) along body +x at its mean distance, seen by a
    camera 5 m beside the plate: 64 x 64 px of 2e-4 rad (the disc ~22 px in radius)."""
    center = MOON_DISTANCE_M * np.array([1.0, 0.0, 0.0])
    moon = moon_body(center, MOON_MEAN_RADIUS_M, MOON_ALBEDO, sun, E_SUN_W_M2)
    camera_body = np.array([0.0, 5.0, 0.0])
    camera = PinholeCamera(focal_length_m=0.075, pixel_pitch_m=15e-6, width_px=64, height_px=64)
    pose = look_at_cam_from_body(camera_body, center, up_hint_body=(0.0, 0.0, 1.0))
    light = LightField(sun, E_SUN_W_M2, np.zeros((25, 3)), bodies=(moon,))
    return camera_body, center, camera, pose, light


def _ray_sphere(origin, dirs, center, radius):
    """First hit of unit rays on a sphere: (hit (N,), point (N, 3))."""
    oc = origin - center
    b = dirs @ oc
    disc = b * b - (oc @ oc - radius * radius)
    hit = disc >= 0.0
    t = -b - np.sqrt(np.where(hit, disc, 0.0))
    return hit & (t > 0), origin + t[:, None] * dirs


def test_the_moon_is_drawn_with_id_2_and_the_lambert_radiance(renderer):
    sun = _unit([-0.5, 0.3, 0.8])  # gibbous: the terminator crosses the disc
    camera_body, center, camera, pose, light = _moon_view(sun)
    image = renderer.render(camera, pose, light, seed=7)
    mask = image.background_mask()
    # Pixel-centre rays by hand, and the corners of each pixel (to skip pixels the limb or
    # the terminator crosses, whose sub-pixel samples see a mixture).
    R_body_from_cam = pose.R_a_from_b.T
    f_px = camera.focal_length_px

    def rays(x, y):
        d = np.stack([(x - camera.cx_px) / f_px, (y - camera.cy_px) / f_px, np.ones(x.size)], -1)
        d = d @ R_body_from_cam.T
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    y, x = np.mgrid[: camera.height_px, : camera.width_px]
    x, y = x.ravel().astype(float), y.ravel().astype(float)
    hit, _ = _ray_sphere(camera_body, rays(x, y), center, MOON_MEAN_RADIUS_M)
    expected_mask = np.where(hit, BACKGROUND_MOON, BACKGROUND_SPACE).reshape(mask.shape)
    assert hit.sum() > 1000
    assert np.array_equal(mask, expected_mask)

    # Each pixel's radiance is the mean over its area (the renderer's sub-pixel samples):
    # here over a 16 x 16 grid of sub-pixel rays, each rho E max(n . s, 0) / pi at its hit.
    def lambert(dx, dy):
        h, p = _ray_sphere(camera_body, rays(x + dx, y + dy), center, MOON_MEAN_RADIUS_M)
        cos_sun = np.maximum(((p - center) / MOON_MEAN_RADIUS_M) @ sun, 0.0)
        return np.where(h, MOON_ALBEDO * E_SUN_W_M2 * cos_sun / math.pi, 0.0)

    offsets = (np.arange(16) + 0.5) / 16 - 0.5
    expected = np.mean([lambert(dx, dy) for dx in offsets for dy in offsets], axis=0)
    got = image.radiance_w_m2_sr.reshape(-1, 3)
    # Pixels wholly on the lit disc (the limb or the terminator crossing a pixel makes its
    # value depend on how the renderer spreads its sub-pixel samples, left out here).
    lit = expected > 0.05 * MOON_ALBEDO * E_SUN_W_M2 / math.pi
    for dx in (-0.5, 0.5):
        for dy in (-0.5, 0.5):
            lit &= lambert(dx, dy) > 0.0
    assert lit.sum() > 500
    # Budget: the 256 random sub-pixel samples against the grid mean, where the radiance
    # changes by up to ~10 % across a pixel (beside the limb), < 1 %; elsewhere float32.
    np.testing.assert_allclose(got[lit], np.repeat(expected[lit, None], 3, axis=1), rtol=1e-2)
    centre = np.abs(got[lit, 1] / expected[lit] - 1.0)
    assert np.median(centre) < 1e-3
    # Pixels none of whose area sees the Moon stay black (space).
    assert np.all(got[expected == 0.0] == 0.0)


def test_moonshine_on_a_plate_facing_the_full_moon_is_the_closed_form(renderer):
    # The Sun behind the plate (body -x), the Moon in front (+x): the full Moon.
    sun = np.array([-1.0, 0.0, 0.0])
    center = MOON_DISTANCE_M * np.array([1.0, 0.0, 0.0])
    moon = moon_body(center, MOON_MEAN_RADIUS_M, MOON_ALBEDO, sun, E_SUN_W_M2)
    expected = subsolar_plate_irradiance(MOON_ALBEDO, E_SUN_W_M2, MOON_MEAN_RADIUS_M, 384_400e3)
    # Far field: (2/3) rho E (R / d)^2 (1 + 3a/4) within 0.1 % (a = 4.5e-3).
    a = MOON_MEAN_RADIUS_M / MOON_DISTANCE_M
    assert expected == pytest.approx((2 / 3) * MOON_ALBEDO * E_SUN_W_M2 * a * a, rel=5e-3)
    # The traced body, integrated independently (midpoint rule, 1e-5), and rendered.
    max_angle = 2.0 * math.asin(a)
    got = axisymmetric_plate_irradiance(moon, np.array([1.0, 0.0, 0.0]), max_angle, 200_000)
    assert got == pytest.approx(expected, rel=1e-4)
    # The plate lies in z = 0: turn the Moon to +z and the Sun to -z (the plate then faces
    # the full Moon) and look at the plate's +z face; 32 x 32 px, 256 paths each.
    turn = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # +x -> +z
    moon_z = moon_body(turn @ center, MOON_MEAN_RADIUS_M, MOON_ALBEDO, turn @ sun, E_SUN_W_M2)
    light = LightField(turn @ sun, 0.0, np.zeros((25, 3)), bodies=(moon_z,))
    camera = PinholeCamera(focal_length_m=0.7, pixel_pitch_m=15e-6, width_px=32, height_px=32)
    pose = look_at_cam_from_body(np.array([0.0, 0.0, 5.0]), np.zeros(3), up_hint_body=(0, 1, 0))
    image = renderer.render(camera, pose, light, seed=13)
    assert image.object_mask.all()
    values = image.radiance_w_m2_sr[..., 1].ravel()
    standard_error = values.std(ddof=1) / math.sqrt(values.size)
    plate_radiance = PLATE_RHO / math.pi * expected
    assert 4 * standard_error < 0.005 * plate_radiance  # the check below is about the bias
    assert values.mean() == pytest.approx(plate_radiance, rel=0.01)
