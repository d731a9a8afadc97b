"""Radiometry of the direct-sun renderer against closed forms.

A Lambertian plate of reflectance rho under collimated irradiance E at incidence angle
theta has radiance L = rho E cos(theta) / pi in every direction (Lambert's law); a
shadowed point receives nothing; the GGX model matches its formula evaluated in float64.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import SunLight
from satsight.render.direct import DirectRenderer
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts

RELATIVE_TOLERANCE = 0.005  # 0.5 % as required for the Lambert plate
E_SUN_W_M2 = 671.5
RHO = (0.5, 0.3, 0.8)
GREY = Material("grey_lambert", RHO, metallic=0.0, roughness=1.0, ior=1.0)
CAMERA = PinholeCamera(focal_length_m=3.0, pixel_pitch_m=15e-6, width_px=64, height_px=64)


def _plate_renderer(material: Material, llvm_variant: str) -> DirectRenderer:
    v, f = plate_parts(size_m=2.0)
    mesh = merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")
    return DirectRenderer(mesh, llvm_variant)


def _camera_above(distance_m: float = 1000.0, tilt_rad: float = 0.0):
    """Camera looking at the plate centre from direction (sin t, 0, cos t)."""
    position = distance_m * np.array([math.sin(tilt_rad), 0.0, math.cos(tilt_rad)])
    return look_at_cam_from_body(position, np.zeros(3), up_hint_body=(0.0, 1.0, 0.0))


def _centre_radiance(image) -> np.ndarray:
    h, w = image.shape
    return image.radiance_w_m2_sr[h // 2 - 4 : h // 2 + 4, w // 2 - 4 : w // 2 + 4].reshape(-1, 3)


def test_lambert_plate_normal_incidence(llvm_variant):
    renderer = _plate_renderer(GREY, llvm_variant)
    image = renderer.render(CAMERA, _camera_above(), SunLight(np.array([0, 0, 1.0]), E_SUN_W_M2))
    expected = np.array(RHO) * E_SUN_W_M2 / math.pi
    on_plate = image.radiance_w_m2_sr[image.object_mask]
    assert on_plate.shape[0] > 100
    np.testing.assert_allclose(
        on_plate, np.broadcast_to(expected, on_plate.shape), rtol=RELATIVE_TOLERANCE
    )
    assert np.all(image.radiance_w_m2_sr[~image.object_mask] == 0.0)


@pytest.mark.parametrize("theta_deg", [0.0, 20.0, 45.0, 60.0, 80.0])
def test_lambert_plate_follows_cosine_and_is_view_independent(llvm_variant, theta_deg):
    renderer = _plate_renderer(GREY, llvm_variant)
    theta = math.radians(theta_deg)
    sun = SunLight(np.array([0.0, math.sin(theta), math.cos(theta)]), E_SUN_W_M2)
    expected = np.array(RHO) * E_SUN_W_M2 * math.cos(theta) / math.pi
    for view_tilt_deg in (0.0, 35.0):
        image = renderer.render(CAMERA, _camera_above(tilt_rad=math.radians(view_tilt_deg)), sun)
        np.testing.assert_allclose(
            _centre_radiance(image), np.broadcast_to(expected, (64, 3)), rtol=RELATIVE_TOLERANCE
        )


def test_plate_lit_from_behind_is_dark(llvm_variant):
    renderer = _plate_renderer(GREY, llvm_variant)
    image = renderer.render(CAMERA, _camera_above(), SunLight(np.array([0.3, 0.0, -1.0]), 1000.0))
    assert image.object_mask.sum() > 100
    assert np.all(image.radiance_w_m2_sr == 0.0)


def test_shadow_of_an_occluder_falls_where_geometry_says(llvm_variant):
    """A 1 m plate 1 m above a 6 m floor, sun at 45 deg towards +y: the shadow is the 1 m
    square shifted by h tan(45) = 1 m towards -y on the floor."""
    floor_v, floor_f = plate_parts(size_m=6.0, z_m=0.0)
    block_v, block_f = plate_parts(size_m=1.0, z_m=1.0)
    mesh = merge_parts(
        [("floor", GREY.name, floor_v, floor_f), ("occluder", GREY.name, block_v, block_f)],
        {GREY.name: GREY},
    )
    renderer = DirectRenderer(mesh, llvm_variant)
    camera = PinholeCamera(focal_length_m=3.0, pixel_pitch_m=15e-6, width_px=200, height_px=200)
    cam_from_body = _camera_above(distance_m=1500.0)
    sun_dir = np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0)
    image = renderer.render(camera, cam_from_body, SunLight(sun_dir, E_SUN_W_M2))
    # Classify floor pixels by back-projecting to the floor plane z = 0.
    body_from_cam = cam_from_body.inverse()
    v, u = np.mgrid[0:200, 0:200]
    rays_cam = camera.ray_directions_cam(np.stack([u, v], -1).reshape(-1, 2).astype(float))
    rays_body = body_from_cam.rotate(rays_cam)
    origin = body_from_cam.t_a_from_b_m
    t_floor = -origin[2] / rays_body[:, 2]
    floor_xy = origin[:2] + t_floor[:, None] * rays_body[:, :2]
    part = image.part_id.reshape(-1)
    lum = image.radiance_w_m2_sr.reshape(-1, 3)[:, 0]
    on_floor = part == 1
    in_shadow = (np.abs(floor_xy[:, 0]) < 0.5) & (np.abs(floor_xy[:, 1] + 1.0) < 0.5)
    # Pixels well inside / outside the predicted shadow (one GSD margin of 7.5 mm * 2).
    inner = (np.abs(floor_xy[:, 0]) < 0.48) & (np.abs(floor_xy[:, 1] + 1.0) < 0.48)
    outer = ~((np.abs(floor_xy[:, 0]) < 0.52) & (np.abs(floor_xy[:, 1] + 1.0) < 0.52))
    visible_floor = on_floor & ~in_shadow
    assert np.count_nonzero(on_floor & inner) > 200  # the shadow is resolved
    assert np.count_nonzero(visible_floor & outer) > 1000
    assert np.all(lum[on_floor & inner] == 0.0)
    lit_expected = RHO[0] * E_SUN_W_M2 * sun_dir[2] / math.pi
    np.testing.assert_allclose(lum[visible_floor & outer], lit_expected, rtol=RELATIVE_TOLERANCE)


def _ggx_reference(n, wi, wo, base, metallic, roughness, ior):
    """The model of satsight.render.ggx written out in float64 numpy (independent code)."""
    h = (wi + wo) / np.linalg.norm(wi + wo)
    ci, co, ch, cd = n @ wi, n @ wo, n @ h, wi @ h
    alpha = roughness**2
    d = alpha**2 / (math.pi * (ch**2 * (alpha**2 - 1) + 1) ** 2)
    k = (roughness + 1) ** 2 / 8
    g = (ci / (ci * (1 - k) + k)) * (co / (co * (1 - k) + k))
    # exact dielectric Fresnel via Snell and the two polarisations
    sin_t = math.sqrt(max(0.0, 1 - cd**2)) / ior
    ct = math.sqrt(1 - sin_t**2)
    rs = ((cd - ior * ct) / (cd + ior * ct)) ** 2
    rp = ((ior * cd - ct) / (ior * cd + ct)) ** 2
    f_d = 0.5 * (rs + rp)
    base = np.asarray(base)
    f_m = base + (1 - base) * (1 - cd) ** 5
    f = metallic * f_m + (1 - metallic) * f_d
    # Diffuse light crosses the interface twice: transmittance 1 - F at n.wi and at n.wo.
    transmitted = (1 - _fresnel(ci, ior)) * (1 - _fresnel(co, ior))
    return (1 - metallic) * transmitted * base / math.pi + f * d * g / (4 * ci * co)


def _fresnel(cos_i: float, ior: float) -> float:
    """Unpolarised reflectance of a dielectric, from Snell's law and both polarisations."""
    sin_t = math.sqrt(max(0.0, 1 - cos_i**2)) / ior
    ct = math.sqrt(1 - sin_t**2)
    rs = ((cos_i - ior * ct) / (cos_i + ior * ct)) ** 2
    rp = ((ior * cos_i - ct) / (ior * cos_i + ct)) ** 2
    return 0.5 * (rs + rp)


@pytest.mark.parametrize(
    ("sun_deg", "view_deg", "metallic", "roughness"),
    [
        (30.0, 30.0, 1.0, 0.3),
        (10.0, 50.0, 0.0, 0.5),
        (60.0, 20.0, 0.5, 0.7),
        (45.0, 44.0, 1.0, 0.15),
    ],
)
def test_ggx_plate_matches_float64_formula(llvm_variant, sun_deg, view_deg, metallic, roughness):
    material = Material("m", (0.9, 0.6, 0.3), metallic, roughness, ior=1.5)
    renderer = _plate_renderer(material, llvm_variant)
    sun_dir = np.array([-math.sin(math.radians(sun_deg)), 0.0, math.cos(math.radians(sun_deg))])
    cam_from_body = _camera_above(distance_m=2000.0, tilt_rad=math.radians(view_deg))
    image = renderer.render(CAMERA, cam_from_body, SunLight(sun_dir, E_SUN_W_M2))
    # The ray through the principal point (between the 4 centre pixels) hits the centre;
    # use the 2x2 centre block whose view directions differ by < 3 urad from the axis.
    wo = cam_from_body.inverse().t_a_from_b_m / np.linalg.norm(cam_from_body.t_a_from_b_m)
    n = np.array([0.0, 0.0, 1.0])
    expected = _ggx_reference(n, sun_dir, wo, material.base_color_rgb, metallic, roughness, 1.5)
    expected *= E_SUN_W_M2 * (n @ sun_dir)
    got = image.radiance_w_m2_sr[31:33, 31:33].reshape(-1, 3)
    np.testing.assert_allclose(got, np.broadcast_to(expected, got.shape), rtol=2e-3)
