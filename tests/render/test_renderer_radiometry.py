"""Radiometry of the radiative renderer against closed forms.

* Lambert plate under the Sun: L = rho E cos(theta) / pi (exact).
* Lambert plate in a constant environment of radiance L_c: L = rho L_c, exactly, both from
  the SH irradiance (unshadowed) and from cosine-sampled environment rays (zero variance).
* Two Lambert plates in a "V" under the Sun with one bounce: L_A(x) = rho_A / pi (E cos
  theta_A + L_B * integral over B of cos cos / r^2 dA), with L_B = rho_B E cos theta_B / pi;
  the geometric integral is evaluated independently with scipy.
* A partly transparent plate over an opaque one: coverage-weighted radiance and a shadow
  transmittance of 1 - alpha.

Statistical tolerances come from the sample counts (Bernoulli variance per ray).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from builders import plate_parts, v_mesh, view_integral_to_b
from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting import sh
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts

E_SUN_W_M2 = 671.5
RHO_A = (0.6, 0.4, 0.8)
RHO_B = (0.9, 0.7, 0.5)
SMALL_CAMERA = PinholeCamera(focal_length_m=3.0, pixel_pitch_m=15e-6, width_px=48, height_px=48)
# Four standard deviations: a false alarm about once in 16 000 checks.
Z_LIMIT = 4.0


def _lambert(name: str, rho) -> Material:
    return Material(name, rho, metallic=0.0, roughness=1.0, ior=1.0)


def _plate_mesh(rho=RHO_A):
    v, f = plate_parts(size_m=2.0)
    material = _lambert("plate_lambert", rho)
    return merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")


def _camera_above(distance_m: float = 1000.0, tilt_rad: float = 0.3):
    position = distance_m * np.array([math.sin(tilt_rad), 0.0, math.cos(tilt_rad)])
    return look_at_cam_from_body(position, np.zeros(3), up_hint_body=(0.0, 1.0, 0.0))


def _constant_environment(radiance_w_m2_sr: float, l_max: int = 4) -> np.ndarray:
    coeffs = np.zeros((sh.sh_count(l_max), 3))
    coeffs[0] = radiance_w_m2_sr * math.sqrt(4.0 * math.pi)  # Y_00 = 1 / sqrt(4 pi)
    return coeffs


def test_lambert_plate_under_the_sun(llvm_variant):
    theta = math.radians(35.0)
    sun = np.array([math.sin(theta), 0.0, math.cos(theta)])
    renderer = Renderer(_plate_mesh(), RenderSettings(), llvm_variant)
    image = renderer.render(SMALL_CAMERA, _camera_above(), LightField.sun_only(sun, E_SUN_W_M2))
    on_plate = image.radiance_w_m2_sr[image.object_mask]
    expected = np.array(RHO_A) * E_SUN_W_M2 * math.cos(theta) / math.pi
    assert on_plate.shape[0] > 100
    np.testing.assert_allclose(on_plate, np.broadcast_to(expected, on_plate.shape), rtol=5e-4)
    assert np.all(image.radiance_w_m2_sr[~image.object_mask] == 0.0)


@pytest.mark.parametrize("environment", ["sampled", "unshadowed"])
def test_lambert_plate_in_constant_environment(llvm_variant, environment):
    """A constant environment L_c gives irradiance pi L_c on a plate: L = rho L_c."""
    l_c = 12.5
    settings = RenderSettings(environment=environment, bounces=1, samples_per_pixel=4)
    light = LightField(np.array([0.0, 0.0, 1.0]), 0.0, _constant_environment(l_c))
    image = Renderer(_plate_mesh(), settings, llvm_variant).render(
        SMALL_CAMERA, _camera_above(), light, seed=3
    )
    on_plate = image.radiance_w_m2_sr[image.object_mask]
    expected = np.array(RHO_A) * l_c
    np.testing.assert_allclose(on_plate, np.broadcast_to(expected, on_plate.shape), rtol=5e-4)


def test_sun_as_sh_on_a_plate_is_the_sh_irradiance(llvm_variant):
    """sun="sh": the diffuse radiance is rho / pi * E * sum_l A_l Y_lm(s) Y_lm(n)."""
    theta = math.radians(50.0)
    s_dir = np.array([math.sin(theta), 0.0, math.cos(theta)])
    settings = RenderSettings(sun="sh", environment="unshadowed", bounces=0, sh_order=4)
    sh_image = Renderer(_plate_mesh(), settings, llvm_variant).render(
        SMALL_CAMERA, _camera_above(), LightField.sun_only(s_dir, E_SUN_W_M2)
    )
    irradiance = sh.evaluate(
        sh.irradiance_coeffs(E_SUN_W_M2 * sh.delta_coeffs(s_dir, 4)), np.array([0.0, 0.0, 1.0])
    )
    # The specular part is zero for an IOR-1 Lambert material, so this is the whole signal.
    expected = np.array(RHO_A) / math.pi * float(irradiance)
    on_plate = sh_image.radiance_w_m2_sr[sh_image.object_mask]
    np.testing.assert_allclose(on_plate, np.broadcast_to(expected, on_plate.shape), rtol=1e-3)
    # Order 4 is a close but not exact stand-in for the delta: cos(50 deg) = 0.643.
    assert abs(float(irradiance) / E_SUN_W_M2 - math.cos(theta)) < 0.05


# --- the "V": two plates and one bounce ------------------------------------------------------


def _lambert_v():
    """The V of Lambert plates A (RHO_A) and B (RHO_B), ``builders.v_mesh``."""
    return v_mesh(_lambert("a_lambert", RHO_A), _lambert("b_lambert", RHO_B))


def test_v_scene_one_bounce_against_closed_form(llvm_variant):
    sun = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
    cos_sun = 1.0 / math.sqrt(2.0)
    camera = PinholeCamera(focal_length_m=0.02, pixel_pitch_m=15e-6, width_px=96, height_px=96)
    position = 30.0 * np.array([1.0, 0.3, 1.0]) / np.linalg.norm([1.0, 0.3, 1.0])
    cam_from_body = look_at_cam_from_body(position, np.array([0.7, 0.0, 0.7]))
    passes = 64
    settings = RenderSettings(environment="off", bounces=1, samples_per_pixel=passes)
    image = Renderer(_lambert_v(), settings, llvm_variant).render(
        camera, cam_from_body, LightField.sun_only(sun, E_SUN_W_M2), seed=11
    )
    on_a = image.part_id == 1
    # Keep pixels whose centre ray hits A away from its edges (no partial coverage).
    v, u = np.nonzero(on_a)
    points_cam = camera.backproject(np.stack([u, v], axis=1).astype(float), image.depth_m[v, u])
    points = cam_from_body.inverse().apply(points_cam)
    inside = (points[:, 0] > 0.05) & (points[:, 0] < 1.95) & (np.abs(points[:, 1]) < 0.95)
    v, u, points = v[inside], u[inside], points[inside]
    step = max(1, len(points) // 150)
    v, u, points = v[::step], u[::step], points[::step]
    assert len(points) > 80

    l_b = np.array(RHO_B) * E_SUN_W_M2 * cos_sun / math.pi
    view = np.array([view_integral_to_b(px, py) for px, py, _ in points])
    direct = np.array(RHO_A) * E_SUN_W_M2 * cos_sun / math.pi
    expected = direct + np.array(RHO_A) / math.pi * view[:, None] * l_b
    rendered = image.radiance_w_m2_sr[v, u]
    # Cosine-sampled bounce rays hit B with probability F = view / pi; each pass then adds
    # rho_A L_B (or nothing): Bernoulli variance per pixel, an upper bound for the
    # stratified (low-discrepancy) passes.
    f_view = view / math.pi
    sigma = np.array(RHO_A) * l_b * np.sqrt(f_view * (1.0 - f_view) / passes)[:, None]
    z_total = (rendered - expected).sum(axis=0) / np.sqrt((sigma**2).sum(axis=0))
    assert np.all(np.abs(z_total) < Z_LIMIT), z_total
    indirect = expected - direct
    relative = np.abs((rendered - expected).mean(axis=0)) / indirect.mean(axis=0)
    assert np.all(relative < 0.01), relative
    assert np.all(np.abs(rendered - expected) < Z_LIMIT * sigma + 1e-3 * expected)


# --- transparency ----------------------------------------------------------------------------


def test_partly_transparent_plate_over_opaque_plate(llvm_variant):
    alpha = 0.3
    front_v, faces = plate_parts(size_m=2.0, z_m=1.0)
    back_v, _ = plate_parts(size_m=2.0, z_m=0.0)
    front = Material("front_glassy", RHO_A, metallic=0.0, roughness=1.0, ior=1.0, alpha=alpha)
    back = _lambert("back_lambert", RHO_B)
    mesh = merge_parts(
        [("front", front.name, front_v, faces), ("back", back.name, back_v, faces)],
        {front.name: front, back.name: back},
        "layers",
    )
    passes = 256
    settings = RenderSettings(environment="off", bounces=0, samples_per_pixel=passes)
    camera = PinholeCamera(focal_length_m=3.0, pixel_pitch_m=15e-6, width_px=24, height_px=24)
    image = Renderer(mesh, settings, llvm_variant).render(
        camera,
        _camera_above(tilt_rad=0.0),
        LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_SUN_W_M2),
        seed=5,
    )
    # Labels: alpha 0.3 is below the label threshold, so the back plate is what is labelled.
    centre = image.part_id[8:16, 8:16]
    assert np.all(centre == 2)
    np.testing.assert_allclose(image.depth_m[8:16, 8:16], 1000.0, atol=1e-3)
    l_front = np.array(RHO_A) * E_SUN_W_M2 / math.pi
    l_back = np.array(RHO_B) * E_SUN_W_M2 / math.pi
    expected = alpha * l_front + (1 - alpha) ** 2 * l_back
    pixels = image.radiance_w_m2_sr[8:16, 8:16].reshape(-1, 3)
    # Per pass: the front with probability alpha, else the back lit with probability
    # 1 - alpha; multinomial variance of those outcomes over all passes of all pixels.
    outcomes = np.array([l_front, l_back, np.zeros(3)])
    probs = np.array([alpha, (1 - alpha) ** 2, (1 - alpha) * alpha])
    variance = (probs[:, None] * outcomes**2).sum(axis=0) - expected**2
    sigma_mean = np.sqrt(variance / (passes * len(pixels)))
    assert np.all(np.abs(pixels.mean(axis=0) - expected) < Z_LIMIT * sigma_mean)


def test_same_seed_same_bytes_other_seed_other_noise(llvm_variant):
    settings = RenderSettings(environment="sampled", bounces=2, samples_per_pixel=2)
    light = LightField(
        np.array([1.0, 0.0, 1.0]), E_SUN_W_M2, _constant_environment(5.0) * [1.0, 0.8, 0.6]
    )
    renderer = Renderer(_lambert_v(), settings, llvm_variant)
    camera = PinholeCamera(focal_length_m=0.02, pixel_pitch_m=15e-6, width_px=32, height_px=32)
    pose = look_at_cam_from_body(np.array([20.0, 6.0, 20.0]), np.array([0.7, 0.0, 0.7]))
    first = renderer.render(camera, pose, light, seed=1).radiance_w_m2_sr
    # Several repeats: a sum whose order depended on thread timing would show here.
    for _ in range(6):
        again = renderer.render(camera, pose, light, seed=1).radiance_w_m2_sr
        assert first.tobytes() == again.tobytes()
    other = renderer.render(camera, pose, light, seed=2).radiance_w_m2_sr
    assert not np.array_equal(first, other)


def _metal(name: str) -> Material:
    return Material(name, (0.9, 0.8, 0.7), metallic=1.0, roughness=0.5, ior=1.5)


def test_unshadowed_environment_ignores_the_other_plate_at_the_last_vertex(llvm_variant):
    """With environment="unshadowed" the last vertex of a path sees the environment as if
    the target were not there: plate A of a metal "V" is as bright as plate A alone, sample
    for sample (same pixels, same random numbers). "sampled" lets plate B shadow it."""
    a_vertices = np.array([[0, -1, 0], [2, -1, 0], [2, 1, 0], [0, 1, 0]], dtype=float)
    b_vertices = np.array([[0, -1, 0], [0, 1, 0], [0, 1, 2], [0, -1, 2]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mats = {"a_metal": _metal("a_metal"), "b_metal": _metal("b_metal")}
    plate_a = ("a", "a_metal", a_vertices, faces)
    alone = merge_parts([plate_a], {"a_metal": mats["a_metal"]}, "a_alone")
    v_shape = merge_parts([plate_a, ("b", "b_metal", b_vertices, faces)], mats, "v")
    light = LightField(np.array([0.0, 0.0, 1.0]), 0.0, _constant_environment(10.0))
    camera = PinholeCamera(focal_length_m=0.02, pixel_pitch_m=15e-6, width_px=64, height_px=64)
    pose = look_at_cam_from_body(np.array([30.0, 4.0, 20.0]), np.array([1.0, 0.0, 0.0]))
    images = {}
    for environment in ("unshadowed", "sampled"):
        # Sample for sample: the footprint grid, whose cells follow each mesh's own box,
        # stays off.
        settings = RenderSettings(
            environment=environment, bounces=0, samples_per_pixel=4, integrate_footprint=False
        )
        for name, mesh in (("alone", alone), ("v", v_shape)):
            images[environment, name] = Renderer(mesh, settings, llvm_variant).render(
                camera, pose, light, seed=4
            )
    # Plate A is part 1 in both meshes; compare where both renders see only it (pixels
    # next to plate B in the image may have sub-pixel rays that meet B).
    near_b = binary_dilation(images["unshadowed", "v"].part_id == 2, iterations=1)
    on_a = (images["unshadowed", "alone"].part_id == 1) & ~near_b
    assert on_a.sum() > 300
    np.testing.assert_allclose(
        images["unshadowed", "v"].radiance_w_m2_sr[on_a],
        images["unshadowed", "alone"].radiance_w_m2_sr[on_a],
        rtol=1e-6,
    )
    # The sampled environment is shadowed by plate B: plate A is darker in the V.
    shadowed = images["sampled", "v"].radiance_w_m2_sr[on_a].mean()
    open_sky = images["sampled", "alone"].radiance_w_m2_sr[on_a].mean()
    assert shadowed < 0.97 * open_sky


@pytest.mark.parametrize("brdf", ["ggx", "improved_phong", "phong"])
def test_unshadowed_sh_diffuse_equals_sampled_environment_on_a_plate(llvm_variant, brdf):
    """A plate cannot shadow itself, so the SH convolution of the diffuse part (exact for
    each model's zonal kernel) plus sampled specular equals fully sampled lighting."""
    material = Material("paint_like", (0.7, 0.5, 0.3), metallic=0.2, roughness=0.5, ior=1.5)
    v, f = plate_parts(size_m=2.0)
    mesh = merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")
    rng = np.random.default_rng(3)
    coeffs = np.zeros((25, 3))
    coeffs[0] = 10.0 * math.sqrt(4.0 * math.pi)
    coeffs[1:9] = rng.normal(scale=2.0, size=(8, 3))  # a smooth, positive-enough sky
    light = LightField(np.array([0.0, 0.0, 1.0]), 0.0, coeffs)
    passes = 256
    images = {}
    for environment in ("sampled", "unshadowed"):
        settings = RenderSettings(
            brdf=brdf, environment=environment, bounces=0, samples_per_pixel=passes
        )
        images[environment] = Renderer(mesh, settings, llvm_variant).render(
            SMALL_CAMERA, _camera_above(), light, seed=8
        )
    mask = images["sampled"].object_mask
    sampled = images["sampled"].radiance_w_m2_sr[mask].astype(np.float64)
    unshadowed = images["unshadowed"].radiance_w_m2_sr[mask].astype(np.float64)
    # Pixel-to-pixel spread of the sampled estimate bounds the noise of the means.
    sigma = np.sqrt(sampled.var(axis=0) / len(sampled) + unshadowed.var(axis=0) / len(sampled))
    difference = unshadowed.mean(axis=0) - sampled.mean(axis=0)
    assert np.all(np.abs(difference) < Z_LIMIT * sigma + 5e-4 * sampled.mean(axis=0)), (
        difference,
        sigma,
    )


def test_regularized_material_is_only_ever_rougher():
    from satsight.render.surface import regularized

    glossy = Material("lens_like", (0.1, 0.1, 0.1), metallic=0.0, roughness=0.02, ior=1.46)
    rough = Material("paint_like", (0.8, 0.8, 0.8), metallic=0.0, roughness=0.8, ior=1.5)
    fixed_g = Material("fixed_gloss", (0.5, 0.5, 0.5), 0.5, 0.1, 1.5, gloss_exponent_g=5000.0)
    assert regularized(glossy, 0.35).roughness == 0.35
    assert regularized(glossy, 0.35).ior == glossy.ior
    assert regularized(rough, 0.35) is rough
    capped = regularized(fixed_g, 0.35)
    assert capped.gloss_exponent_g == pytest.approx(capped.phong_gloss_exponent)
    assert capped.gloss_exponent_g < 5000.0
    assert regularized(glossy, 0.0) is glossy
