"""Smooth shading normals, textures and normal maps in the renderer, against closed forms.

* Lambert sphere (radius R, reflectance rho, collimated irradiance E, phase angle a):
  the radiant intensity towards the observer is

      I(a) = 2 rho E R^2 / (3 pi) * (sin a + (pi - a) cos a)

  (integrate L = rho E cos(i) / pi times the projected area cos(e) dA over the lit and
  visible lune; Russell 1916, "On the light variations of asteroids and satellites",
  ApJ 43, 173, the Lambert-sphere phase function). Measured from the image as
  I = sum(L) * pixel solid angle * D^2.
* Glossy sphere: with a GGX metal of reflectance 1 (Fresnel 1, Smith masking) the
  intensity is I(a) = E R^2 / 4 * integral over the normals n of D(n.h) G1(n.s) G1(n.v)
  (f cos(i) cos(e) = D G / 4), evaluated here by float64 quadrature.
* Textured Lambert plate: L = t(u, v) E cos(theta) / pi, t the bilinearly filtered,
  sRGB-decoded texture at the hit's (u, v), computed here independently in numpy.
* Normal map: a Lambert plate whose map tilts the normal to n' gives L = rho E n'.s / pi.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField, SunLight
from satsight.render.direct import DirectRenderer
from satsight.render.renderer import Renderer
from satsight.render.settings import DIRECT_SUN_ONLY, RenderSettings
from satsight.scene.loading import load_mesh
from satsight.scene.materials import FIRST_MATERIALS, Material
from satsight.scene.mesh import PartSurface, merge_parts
from satsight.scene.textures import SurfaceTextures, TextureImage, decode, normal_map_pixels

E_W_M2 = 1000.0
WHITE = FIRST_MATERIALS["lambert_white"]  # rho = 1, no specular lobe (IOR 1)
METAL = Material("mirror_metal", (1.0, 1.0, 1.0), metallic=1.0, roughness=0.3, ior=1.5)
FLOAT32_REL = 2e-4  # float32 shading and 8-bit textures decoded exactly
DISTANCE_M = 1000.0
SPHERE_CAMERA = PinholeCamera(1.0, 15e-6, 160, 160)  # a unit sphere spans 133 px
PIXEL_SR = (15e-6 / 1.0) ** 2


# --- spheres --------------------------------------------------------------------------------
def _spheres(material: Material, subdivisions: int = 2):
    """The same icosphere (unit radius) flat and with radial vertex normals."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    materials = {material.name: material}
    flat = merge_parts([("sphere", material.name, v, f)], materials)
    smooth = merge_parts(
        [("sphere", material.name, v, f, PartSurface(vertex_normals=v))], materials
    )
    return flat, smooth


def _phase_pose(phase_rad: float):
    """Sun along +z; camera DISTANCE_M away at ``phase_rad`` from it in the x-z plane."""
    position = DISTANCE_M * np.array([math.sin(phase_rad), 0.0, math.cos(phase_rad)])
    return look_at_cam_from_body(position, np.zeros(3), up_hint_body=np.array([0.0, 1.0, 0.0]))


def _intensity(renderer, phase_rad: float):
    """(radiant intensity W/sr, projected area m^2 from the mask) of the sphere."""
    light = LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_W_M2)
    image = renderer.render(SPHERE_CAMERA, _phase_pose(phase_rad), light)
    scale = PIXEL_SR * DISTANCE_M**2
    return float(image.radiance_w_m2_sr[..., 0].sum()) * scale, float(
        image.object_mask.sum()
    ) * scale


def lambert_phase(a: float) -> float:
    """I(a) / (rho E R^2) of a Lambert sphere (module docstring)."""
    return 2.0 / (3.0 * math.pi) * (math.sin(a) + (math.pi - a) * math.cos(a))


PHASES_DEG = (0, 30, 60, 90, 120, 150)
LAMBERT_PHASE_TOLERANCE = 0.006  # of I(0), both shadings (measured 0.0027 flat, 0.0038 smooth)


@pytest.fixture(scope="module")
def lambert_curves(llvm_variant):
    settings = RenderSettings(environment="off", bounces=0, supersampling=4)
    curves = {}
    for name, mesh in zip(("flat", "smooth"), _spheres(WHITE), strict=True):
        renderer = Renderer(mesh, settings, llvm_variant)
        curves[name] = [_intensity(renderer, math.radians(d)) for d in PHASES_DEG]
    return curves


def test_lambert_sphere_follows_the_phase_law(lambert_curves):
    """Measured intensity, with R^2 taken from the rendered disc (the icosphere is
    inscribed in the unit sphere), against Russell's closed form, for both shadings.

    Disc-integrated light is an average over facets, and a facet's mean interpolated
    normal is its own normal, so smooth normals change this curve little; they matter
    for the resolved image and for glossy surfaces (tests below)."""
    for name, curve in lambert_curves.items():
        _, area0 = curve[0]
        r2 = area0 / math.pi
        for deg, (intensity, _) in zip(PHASES_DEG, curve, strict=True):
            expected = lambert_phase(math.radians(deg)) * E_W_M2 * r2
            error = abs(intensity - expected) / (lambert_phase(0.0) * E_W_M2 * r2)
            assert error <= LAMBERT_PHASE_TOLERANCE, (name, deg, error)


def _sphere_pixels(renderer, phase_rad: float):
    """Radiance, analytic sphere radiance at each hit and label normals vs radial."""
    pose = _phase_pose(phase_rad)
    light = LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_W_M2)
    image = renderer.render(SPHERE_CAMERA, pose, light)
    h, w = image.shape
    v, u = np.mgrid[0:h, 0:w]
    rays = SPHERE_CAMERA.ray_directions_cam(np.stack([u, v], -1).reshape(-1, 2).astype(float))
    p_cam = rays * (image.depth_m.reshape(-1, 1) / rays[:, 2:3])
    p_body = pose.inverse().apply(p_cam)
    radial = p_body / np.linalg.norm(p_body, axis=1, keepdims=True)
    truth = E_W_M2 * np.maximum(radial[:, 2], 0.0) / math.pi
    normals_body = image.normals_cam.reshape(-1, 3) @ pose.R_a_from_b
    return image, truth, radial, normals_body


def test_smooth_sphere_pixels_follow_the_sphere_and_flat_facets_do_not(llvm_variant):
    """Per pixel, radiance against a true sphere's at the hit's radial direction, and the
    normal label against that direction: smooth within 1.5 % RMS and 1 degree, flat
    facets several times worse."""
    errors = {}
    for name, mesh in zip(("flat", "smooth"), _spheres(WHITE), strict=True):
        renderer = Renderer(mesh, DIRECT_SUN_ONLY, llvm_variant)
        image, truth, radial, normals = _sphere_pixels(renderer, math.radians(40.0))
        lit = image.object_mask.reshape(-1) & (radial[:, 2] > 0.2)
        measured = image.radiance_w_m2_sr[..., 0].reshape(-1)[lit]
        rms = float(np.sqrt(np.mean((measured / truth[lit] - 1.0) ** 2)))
        seen = image.object_mask.reshape(-1)
        angle = np.degrees(np.arccos(np.clip(np.sum(normals[seen] * radial[seen], 1), -1, 1)))
        errors[name] = (rms, float(np.percentile(angle, 99)))
    assert errors["smooth"][0] <= 0.015, errors
    assert errors["flat"][0] >= 3.0 * errors["smooth"][0], errors
    assert errors["smooth"][1] <= 1.0, errors
    assert errors["flat"][1] >= 5.0, errors


def _glossy_sphere_intensity(phase_rad: float, roughness: float) -> float:
    """I / (E R^2) of a sphere of GGX metal with Fresnel 1 and Smith masking (float64
    quadrature over the normals, in polar coordinates about the half vector)."""
    alpha = roughness**2
    s = np.array([0.0, 0.0, 1.0])
    v = np.array([math.sin(phase_rad), 0.0, math.cos(phase_rad)])
    h = (s + v) / np.linalg.norm(s + v)
    t1 = np.cross(h, [0.0, 1.0, 0.0]) if abs(h[1]) < 0.9 else np.cross(h, [1.0, 0.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(h, t1)
    x, w = np.polynomial.legendre.leggauss(400)
    theta = 0.5 * math.pi * (x + 1.0) / 2.0  # [0, pi/2]: D is negligible beyond
    wt = w * 0.25 * math.pi
    phi = np.linspace(0.0, 2.0 * math.pi, 721)[:-1]
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    n = (
        np.cos(th)[..., None] * h
        + (np.sin(th) * np.cos(ph))[..., None] * t1
        + (np.sin(th) * np.sin(ph))[..., None] * t2
    )
    cos_h = np.cos(th)
    d = alpha**2 / (math.pi * (cos_h**2 * (alpha**2 - 1.0) + 1.0) ** 2)

    def g1(c):
        c = np.maximum(c, 0.0)
        return 2.0 * c / np.maximum(c + np.sqrt(alpha**2 + (1.0 - alpha**2) * c * c), 1e-300)

    integrand = d * g1(n @ s) * g1(n @ v) / 4.0 * np.sin(th)
    return float(np.sum(integrand * wt[:, None]) * (2.0 * math.pi / len(phi)))


def test_glossy_sphere_light_curve_is_smooth_only_with_smooth_normals(llvm_variant):
    """Flat facets glint only where a facet normal meets the half vector: the light curve
    of a glossy icosphere jumps by factors of 2-4 with phase. With smooth normals it
    follows the true sphere's (quadrature) to a few per cent."""
    settings = RenderSettings(environment="off", bounces=0, supersampling=4, ggx_masking="smith")
    phases_rad = [math.radians(deg) for deg in range(0, 121, 15)]
    # I / (E R^2) of the true sphere, once per phase for both shadings.
    sphere = [_glossy_sphere_intensity(a, METAL.roughness) for a in phases_rad]
    ratios = {}
    for name, mesh in zip(("flat", "smooth"), _spheres(METAL), strict=True):
        renderer = Renderer(mesh, settings, llvm_variant)
        ratios[name] = []
        for a, unit_intensity in zip(phases_rad, sphere, strict=True):
            intensity, area = _intensity(renderer, a)
            expected = unit_intensity * E_W_M2 * area / math.pi
            ratios[name].append(intensity / expected)
    smooth, flat = np.array(ratios["smooth"]), np.array(ratios["flat"])
    assert np.all(np.abs(smooth - 1.0) <= 0.05), smooth
    assert np.max(np.abs(flat - 1.0)) >= 0.3, flat
    assert np.std(flat) >= 5.0 * np.std(smooth), (flat, smooth)


# --- textures -------------------------------------------------------------------------------
TEXTURE = np.array(
    [
        [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]],
        [[128, 128, 128], [30, 60, 90], [200, 100, 50], [10, 10, 10]],
        [[64, 200, 16], [255, 255, 0], [0, 0, 0], [90, 30, 220]],
    ],
    dtype=np.uint8,
)  # 3 rows x 4 columns, no symmetry: a flip or transpose shows


def reference_texture(pixels: np.ndarray, uv: np.ndarray, wrap: str) -> np.ndarray:
    """Bilinear lookup (linear light) in float64: texel (i, j) centred at ((i + 0.5) / W,
    (j + 0.5) / H) with j counted from the bottom row."""
    values = decode(np.flipud(pixels), "srgb")  # row 0 at v = 0
    h, w = values.shape[:2]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]

    def index(i, n):
        if wrap == "clamp":
            return np.clip(i, 0, n - 1).astype(int)
        if wrap == "mirror":
            m = np.mod(i, 2 * n)
            return np.where(m >= n, 2 * n - 1 - m, m).astype(int)
        return np.mod(i, n).astype(int)

    xs, ys = [index(x0, w), index(x0 + 1, w)], [index(y0, h), index(y0 + 1, h)]
    top = (1 - fx) * values[ys[0], xs[0]] + fx * values[ys[0], xs[1]]
    bottom = (1 - fx) * values[ys[1], xs[0]] + fx * values[ys[1], xs[1]]
    return (1 - fy) * top + fy * bottom


GREY = Material("grey_lambert", (0.3, 0.3, 0.3), metallic=0.0, roughness=1.0, ior=1.0)


def textured_plate(
    wrap: str = "clamp", tiles: float = 1.0, material: Material = WHITE, factors="multiply"
):
    """A 2 m plate in z = 0 (normal +z) with u = (x + 1) / 2 * tiles, v = (y + 1) / 2 * tiles."""
    v, f = plate_parts(size_m=2.0)
    uv = (v[:, :2] + 1.0) / 2.0 * tiles
    image = TextureImage(TEXTURE, "srgb", (wrap, wrap))
    surface = PartSurface(vertex_uv=uv, textures=SurfaceTextures(base_color=image, factors=factors))
    return merge_parts([("plate", material.name, v, f, surface)], {material.name: material})


def _plate_hits(camera: PinholeCamera, pose):
    """Body-frame hit points of the pixel-centre rays on the plane z = 0, and which hit
    the 2 m plate."""
    h, w = camera.height_px, camera.width_px
    v, u = np.mgrid[0:h, 0:w]
    rays = camera.ray_directions_cam(np.stack([u, v], -1).reshape(-1, 2).astype(float))
    body_from_cam = pose.inverse()
    d = body_from_cam.rotate(rays)
    o = body_from_cam.t_a_from_b_m
    t = -o[2] / d[:, 2]
    p = o + t[:, None] * d
    on = np.all(np.abs(p[:, :2]) < 1.0 - 1e-3, axis=1)
    return p, on


PLATE_CAMERA = PinholeCamera(3.0, 15e-6, 96, 96)  # 2 m at 1 km: 400 px, a corner in view


@pytest.mark.parametrize(
    ("wrap", "tiles", "brdf", "material", "factors", "scale"),
    [
        ("clamp", 1.0, "ggx", WHITE, "multiply", 1.0),
        ("repeat", 2.5, "ggx", WHITE, "multiply", 1.0),
        ("mirror", 2.5, "ggx", GREY, "multiply", 0.3),
        ("clamp", 1.0, "phong", GREY, "multiply", 0.3),
        ("repeat", 1.5, "ggx", GREY, "replace", 1.0),
        ("repeat", 1.5, "phong", GREY, "replace", 1.0),
    ],
)
def test_textured_lambert_plate_radiance_follows_its_texture(
    llvm_variant, wrap, tiles, brdf, material, factors, scale
):
    """L = factor x t(u, v) x E cos / pi (``replace``: t alone), for GGX and Phong."""
    mesh = textured_plate(wrap, tiles, material, factors)
    theta = math.radians(35.0)
    light = LightField.sun_only(np.array([math.sin(theta), 0.0, math.cos(theta)]), E_W_M2)
    image_px = PinholeCamera(0.6, 15e-6, 128, 128)  # the whole plate: ~102 px across
    pose = look_at_cam_from_body(
        DISTANCE_M * np.array([0.2, -0.1, 1.0]), np.zeros(3), up_hint_body=np.array([0, 1.0, 0])
    )
    # The texture at each pixel centre (the footprint grid, which averages it over the
    # pixel, off).
    settings = DIRECT_SUN_ONLY.with_(brdf=brdf, integrate_footprint=False)
    image = Renderer(mesh, settings, llvm_variant).render(image_px, pose, light)
    p, on = _plate_hits(image_px, pose)
    uv = (p[on, :2] + 1.0) / 2.0 * tiles
    texture = reference_texture(TEXTURE, uv, wrap)
    expected = scale * texture * E_W_M2 * math.cos(theta) / math.pi
    measured = image.radiance_w_m2_sr.reshape(-1, 3)[on]
    assert on.sum() > 5000
    scale = E_W_M2 / math.pi
    np.testing.assert_allclose(measured, expected, rtol=FLOAT32_REL, atol=FLOAT32_REL * scale)


def test_far_textured_plate_shows_the_texture_mean(llvm_variant):
    """Mip-mapping: with many texels per pixel each pixel holds the texture's mean
    (linear light), not a random texel."""
    mesh = textured_plate("repeat", tiles=256.0)  # 2 mm texels, 15 per 3 cm pixel
    sun = SunLight(np.array([0.0, 0.0, 1.0]), E_W_M2)
    camera = PinholeCamera(0.5, 15e-6, 24, 24)
    pose = look_at_cam_from_body(
        DISTANCE_M * np.array([0.0, 0.0, 1.0]), np.zeros(3), up_hint_body=np.array([0, 1.0, 0])
    )
    image = DirectRenderer(mesh, llvm_variant).render(camera, pose, sun)
    inner = image.radiance_w_m2_sr[image.object_mask]
    mean = decode(TEXTURE, "srgb").reshape(-1, 3).mean(axis=0) * E_W_M2 / math.pi
    assert len(inner) == 24 * 24
    # The 1 x 1 level is the mean to 8-bit precision (each level is re-encoded).
    np.testing.assert_allclose(inner, np.broadcast_to(mean, inner.shape), rtol=0.02)


def _plate_hits_at(camera: PinholeCamera, pose, offsets_px: np.ndarray):
    """Body-frame hit points on the plane z = 0 of the rays through every pixel centre
    shifted by each of ``offsets_px`` ((K, 2), px): shape (H * W, K, 3); and which pixels
    have all K hits on the 2 m plate."""
    h, w = camera.height_px, camera.width_px
    v, u = np.mgrid[0:h, 0:w]
    centres = np.stack([u, v], -1).reshape(-1, 1, 2).astype(float)
    positions = (centres + offsets_px[None]).reshape(-1, 2)
    body_from_cam = pose.inverse()
    d = body_from_cam.rotate(camera.ray_directions_cam(positions))
    o = body_from_cam.t_a_from_b_m
    p = o + (-o[2] / d[:, 2])[:, None] * d
    p = p.reshape(h * w, len(offsets_px), 3)
    on = np.all(np.abs(p[..., :2]) < 1.0 - 1e-3, axis=(1, 2))
    return p, on


# The plate of ``textured_plate`` with 16 tiles (texels of 3.1 cm x 4.2 cm) seen from 1 km
# through a 0.6 m lens: 2.5 cm pixels, so every lookup is still in the full-size level
# (magnification) and the texture changes across a pixel by up to a texel step.
SUBPIXEL_TILES = 16.0
SUBPIXEL_CAMERA = PinholeCamera(0.6, 15e-6, 64, 64)
SUBPIXEL_POSE = look_at_cam_from_body(
    DISTANCE_M * np.array([0.1, -0.05, 1.0]), np.zeros(3), up_hint_body=np.array([0, 1.0, 0])
)
SUBPIXEL_SUN = LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_W_M2)


@pytest.mark.parametrize("supersampling", [2, 4])
def test_supersampled_pixels_average_the_texture_at_their_strata_centres(
    llvm_variant, supersampling
):
    """With ``supersampling`` s and one path per stratum a pixel is the mean of the s x s
    stratum centres (x + (k + 0.5) / s - 0.5, same in y), each the bilinear texture there."""
    s = supersampling
    mesh = textured_plate("repeat", tiles=SUBPIXEL_TILES)
    settings = DIRECT_SUN_ONLY.with_(supersampling=s, integrate_footprint=False)
    image = Renderer(mesh, settings, llvm_variant).render(
        SUBPIXEL_CAMERA, SUBPIXEL_POSE, SUBPIXEL_SUN
    )
    centres = (np.arange(s) + 0.5) / s - 0.5
    offsets = np.stack(np.meshgrid(centres, centres), -1).reshape(-1, 2)
    p, on = _plate_hits_at(SUBPIXEL_CAMERA, SUBPIXEL_POSE, offsets)
    uv = (p[on, :, :2] + 1.0) / 2.0 * SUBPIXEL_TILES
    texture = reference_texture(TEXTURE, uv.reshape(-1, 2), "repeat").reshape(*uv.shape[:2], 3)
    expected = texture.mean(axis=1) * E_W_M2 / math.pi
    measured = image.radiance_w_m2_sr.reshape(-1, 3)[on]
    assert on.sum() > 3000
    # The texture's steps within a pixel (some % of the texel contrast) are far above
    # float32 shading error: a wrong stratum position shows.
    scale = E_W_M2 / math.pi
    np.testing.assert_allclose(measured, expected, rtol=FLOAT32_REL, atol=FLOAT32_REL * scale)


def test_jittered_paths_average_the_texture_over_the_pixel_area(llvm_variant):
    """With several paths per pixel their sub-pixel positions spread over the pixel (the
    low-discrepancy sequence with a random shift per pixel): the pixel tends to the
    texture's mean over the pixel's area, here a 32 x 32 midpoint rule."""
    spp = 64
    mesh = textured_plate("repeat", tiles=SUBPIXEL_TILES)
    settings = DIRECT_SUN_ONLY.with_(samples_per_pixel=spp, integrate_footprint=False)
    image = Renderer(mesh, settings, llvm_variant).render(
        SUBPIXEL_CAMERA, SUBPIXEL_POSE, SUBPIXEL_SUN
    )
    grid = (np.arange(32) + 0.5) / 32 - 0.5
    offsets = np.stack(np.meshgrid(grid, grid), -1).reshape(-1, 2)
    p, on = _plate_hits_at(SUBPIXEL_CAMERA, SUBPIXEL_POSE, offsets)
    uv = (p[on, :, :2] + 1.0) / 2.0 * SUBPIXEL_TILES
    texture = reference_texture(TEXTURE, uv.reshape(-1, 2), "repeat").reshape(*uv.shape[:2], 3)
    expected = texture.mean(axis=1) * E_W_M2 / math.pi
    spread = texture.std(axis=1) * E_W_M2 / math.pi
    measured = image.radiance_w_m2_sr.reshape(-1, 3)[on]
    assert on.sum() > 3000
    # Independent uniform positions would leave a standard error spread / sqrt(spp) per
    # pixel; the stratified sequence does better, so 4 of those bound every pixel. Pixels
    # across a texel step (spread > 0) are where a pixel-centre sample would be off by up
    # to half the step: they must have moved to the area mean.
    bound = 4.0 * spread / math.sqrt(spp) + FLOAT32_REL * E_W_M2 / math.pi
    assert np.all(np.abs(measured - expected) <= bound)
    steps = spread.max(axis=1) > 0.05 * E_W_M2 / math.pi
    assert steps.sum() > 50
    p_centre, _ = _plate_hits_at(SUBPIXEL_CAMERA, SUBPIXEL_POSE, np.zeros((1, 2)))
    uv_centre = (p_centre[on, 0, :2] + 1.0) / 2.0 * SUBPIXEL_TILES
    centre = reference_texture(TEXTURE, uv_centre, "repeat") * E_W_M2 / math.pi
    centre_error = np.abs(centre - expected)[steps]
    assert np.abs(measured - expected)[steps].mean() < 0.25 * centre_error.mean()


def test_loaded_obj_plate_renders_its_map_kd(llvm_variant, tmp_path: Path):
    """OBJ + MTL + PNG: the loaded plate's radiance is Kd x map_Kd x E cos / pi."""
    Image.fromarray(TEXTURE).save(tmp_path / "paint.png")
    (tmp_path / "plate.mtl").write_text("newmtl paint\nKd 0.5 0.5 0.5\nNi 1.0\nmap_Kd paint.png\n")
    (tmp_path / "plate.obj").write_text(
        "mtllib plate.mtl\no plate\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl paint\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    )
    mesh = load_mesh(tmp_path / "plate.obj")
    assert mesh.part_material(0).f0 == 0.0  # Ni 1: Lambertian
    sun = SunLight(np.array([0.0, 0.0, 1.0]), E_W_M2)
    camera = PinholeCamera(0.6, 15e-6, 128, 128)
    pose = look_at_cam_from_body(
        DISTANCE_M * np.array([0.0, 0.0, 1.0]), np.zeros(3), up_hint_body=np.array([0, 1.0, 0])
    )
    renderer = DirectRenderer(mesh, llvm_variant)
    renderer.settings = renderer.settings.with_(integrate_footprint=False)  # pixel centres
    image = renderer.render(camera, pose, sun)
    p, on = _plate_hits(camera, pose)
    uv = (p[on, :2] + 1.0) / 2.0
    # MTL roughness defaults to 0.5 with GGX; Ni 1 leaves the diffuse part only.
    expected = 0.5 * reference_texture(TEXTURE, uv, "repeat") * E_W_M2 / math.pi
    measured = image.radiance_w_m2_sr.reshape(-1, 3)[on]
    np.testing.assert_allclose(measured, expected, rtol=FLOAT32_REL, atol=1e-4 * E_W_M2)


# --- normal maps and light leaks ------------------------------------------------------------
def normal_mapped_plate(normal_tangent: np.ndarray, scale: float = 1.0):
    """A Lambert-white plate in z = 0 whose normal map holds one tangent-space normal
    (u along +x, v along +y)."""
    v, f = plate_parts(size_m=2.0)
    pixels = normal_map_pixels(np.broadcast_to(normal_tangent, (4, 4, 3)))
    textures = SurfaceTextures(normal=TextureImage(pixels, "linear"), normal_scale=scale)
    surface = PartSurface(vertex_uv=(v[:, :2] + 1.0) / 2.0, textures=textures)
    mesh = merge_parts([("plate", WHITE.name, v, f, surface)], {WHITE.name: WHITE}, "plate")
    decoded = 2.0 * decode(pixels[0, 0], "linear") - 1.0
    decoded[:2] *= scale
    return mesh, decoded / np.linalg.norm(decoded)


@pytest.mark.parametrize(
    ("tilt", "side"),
    [((0.5, 0.0), 1.0), ((0.0, 0.5), 1.0), ((-0.3, 0.4), 1.0), ((0.5, 0.0), -1.0)],
)
def test_normal_map_tilt_changes_radiance_as_the_tilted_cosine(llvm_variant, tilt, side):
    """L = rho E max(n'.s, 0) / pi with n' the map's normal in the plate's frame; seen
    from behind the plate the whole mapped normal turns over."""
    n_tangent = np.array([tilt[0], tilt[1], 1.0])
    mesh, n_mapped = normal_mapped_plate(n_tangent / np.linalg.norm(n_tangent))
    renderer = DirectRenderer(mesh, llvm_variant)
    camera = PinholeCamera(3.0, 15e-6, 32, 32)
    pose = look_at_cam_from_body(
        side * DISTANCE_M * np.array([0.0, 0.0, 1.0]), np.zeros(3), np.array([0, 1.0, 0])
    )
    n_seen = side * n_mapped
    for sun_dir in ([0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, -0.6, 0.8], [-0.5, 0.5, 0.7071]):
        s = np.array(sun_dir) * np.array([1.0, 1.0, side])
        s /= np.linalg.norm(s)
        image = renderer.render(camera, pose, SunLight(s, E_W_M2))
        expected = E_W_M2 * max(float(n_seen @ s), 0.0) / math.pi
        got = image.radiance_w_m2_sr[image.object_mask][:, 0]
        assert got.size == 32 * 32
        np.testing.assert_allclose(got, expected, rtol=FLOAT32_REL, atol=1e-4), sun_dir


def test_normal_scale_tilts_further(llvm_variant):
    mesh, n_mapped = normal_mapped_plate(np.array([0.3, 0.0, 1.0]) / math.hypot(0.3, 1.0), 2.0)
    assert n_mapped[0] / n_mapped[2] == pytest.approx(0.6, abs=0.01)
    camera = PinholeCamera(3.0, 15e-6, 16, 16)
    pose = look_at_cam_from_body(DISTANCE_M * np.array([0, 0, 1.0]), np.zeros(3), (0, 1.0, 0))
    s = np.array([0.8, 0.0, 0.6])
    image = DirectRenderer(mesh, llvm_variant).render(camera, pose, SunLight(s, E_W_M2))
    got = image.radiance_w_m2_sr[image.object_mask][:, 0]
    np.testing.assert_allclose(got, E_W_M2 * (n_mapped @ s) / math.pi, rtol=FLOAT32_REL)


# --- stochastic texture filtering: the footprint's mean radiance, not its mean normal -------
def cone_normal_map(tilt_rad: float) -> np.ndarray:
    """4 x 4 normal-map pixels whose every 2 x 2 block holds four normals tilted by
    ``tilt_rad`` towards +u, +v, -v and -u: coarser levels hold their mean, (0, 0, cos)."""
    s, c = math.sin(tilt_rad), math.cos(tilt_rad)
    block = np.array([[[s, 0, c], [0, s, c]], [[0, -s, c], [-s, 0, c]]])
    return normal_map_pixels(np.tile(block, (2, 2, 1)))


@pytest.mark.parametrize("texture_filter", ["stochastic", "mip"])
def test_far_normal_mapped_plate_with_stochastic_filtering_keeps_the_mean_radiance(
    llvm_variant, texture_filter
):
    """A Lambert plate (rho = 1) with 1 mm normal-map texels (4 mm tiles) under a grazing
    Sun, seen with 2.5 cm pixels: its mean radiance over the full-size texture is the mean
    of E max(n'.s, 0) / pi over a tile, n' the normalised bilinear map normal (numpy, on a
    256 x 256 grid). ``stochastic`` takes one full-size point of each pixel's footprint at
    random, so the frame's mean tends to it with standard error std / sqrt(pixels); ``mip``
    shades the tile's mean normal (0, 0, 1) (to 8-bit rounding), which misses it by far
    more: the mean of a clamped cosine is not the cosine of the mean normal."""
    pixels = cone_normal_map(math.radians(30.0))
    v, f = plate_parts(size_m=2.0)
    tiles = 500.0
    uv = (v[:, :2] + 1.0) / 2.0 * tiles
    textures = SurfaceTextures(normal=TextureImage(pixels, "linear"))
    mesh = merge_parts(
        [("plate", WHITE.name, v, f, PartSurface(vertex_uv=uv, textures=textures))],
        {WHITE.name: WHITE},
    )
    sun = np.array([math.sin(math.radians(85.0)), 0.0, math.cos(math.radians(85.0))])
    pose = look_at_cam_from_body(
        DISTANCE_M * np.array([0.05, 0.03, 1.0]), np.zeros(3), np.array([0, 1.0, 0])
    )
    camera = PinholeCamera(0.6, 15e-6, 48, 48)
    settings = DIRECT_SUN_ONLY.with_(integrate_footprint=False, texture_filter=texture_filter)
    image = Renderer(mesh, settings, llvm_variant).render(
        camera, pose, LightField.sun_only(sun, E_W_M2)
    )
    assert image.object_mask.all()
    measured = float(image.radiance_w_m2_sr[..., 0].mean())
    # The closed form over one tile: texel (i, j) centred at ((i + 0.5) / 4, (j + 0.5) / 4),
    # v from the bottom row, repeat wrap.
    normals = 2.0 * decode(np.flipud(pixels), "linear") - 1.0
    grid = (np.arange(256) + 0.5) / 256 * 4 - 0.5
    x0 = np.floor(grid).astype(int)
    fx = (grid - x0)[:, None]
    i0, i1 = np.mod(x0, 4), np.mod(x0 + 1, 4)
    rows = [(1 - fx) * normals[j][i0] + fx * normals[j][i1] for j in range(4)]  # along u
    rows = np.stack(rows)  # (4 rows j, 256 u, 3)
    fy = (grid - x0)[:, None, None]
    n = (1 - fy) * rows[i0] + fy * rows[i1]  # (256 v, 256 u, 3)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    radiance = E_W_M2 * np.maximum(n @ sun, 0.0) / math.pi
    expected = float(radiance.mean())
    standard_error = float(radiance.std()) / math.sqrt(image.object_mask.sum())
    if texture_filter == "stochastic":
        assert abs(measured - expected) < 4.0 * standard_error
    else:
        assert abs(measured - expected) > 10.0 * standard_error


def test_plate_lit_from_behind_stays_black_with_a_tilted_normal_map(llvm_variant):
    """The Sun 10 degrees below the plate, the map's normal tilted 60 degrees towards it
    (so n'.s = 0.77): the side facing the camera is unlit all the same."""
    tilted = np.array([math.sin(math.radians(60.0)), 0.0, math.cos(math.radians(60.0))])
    mesh, n_mapped = normal_mapped_plate(tilted)
    s = np.array([math.cos(math.radians(10.0)), 0.0, -math.sin(math.radians(10.0))])
    assert n_mapped @ s > 0.7 and s[2] < 0
    camera = PinholeCamera(3.0, 15e-6, 32, 32)
    pose = look_at_cam_from_body(DISTANCE_M * np.array([0, 0, 1.0]), np.zeros(3), (0, 1.0, 0))
    image = DirectRenderer(mesh, llvm_variant).render(camera, pose, SunLight(s, E_W_M2))
    assert image.object_mask.sum() == 32 * 32
    assert np.all(image.radiance_w_m2_sr == 0.0)


@pytest.mark.parametrize("bounces", [1, 2])
def test_plate_lit_from_behind_stays_black_with_bounces(llvm_variant, bounces):
    """The Sun on the back of the plate, inter-reflection on: bounce directions sampled
    about the front's tilted shading normal that point below the geometric surface
    count as absent, and the plate shadows itself, so the front stays black."""
    tilted = np.array([math.sin(math.radians(60.0)), 0.0, math.cos(math.radians(60.0))])
    mesh, _ = normal_mapped_plate(tilted)
    s = np.array([-math.cos(math.radians(10.0)), 0.0, -math.sin(math.radians(10.0))])
    settings = RenderSettings(environment="off", bounces=bounces, samples_per_pixel=16)
    renderer = Renderer(mesh, settings, llvm_variant)
    camera = PinholeCamera(3.0, 15e-6, 32, 32)
    light = LightField.sun_only(s, E_W_M2)
    above = look_at_cam_from_body(DISTANCE_M * np.array([0, 0, 1.0]), np.zeros(3), (0, 1.0, 0))
    below = look_at_cam_from_body(DISTANCE_M * np.array([0, 0, -1.0]), np.zeros(3), (0, 1.0, 0))
    back = renderer.render(camera, below, light, seed=3)
    assert back.radiance_w_m2_sr[back.object_mask].mean() > 100.0  # the light is there
    front = renderer.render(camera, above, light, seed=3)
    assert front.object_mask.sum() == 32 * 32
    assert np.all(front.radiance_w_m2_sr == 0.0)


@pytest.mark.parametrize("brdf", ["ggx", "phong", "improved_phong"])
def test_light_below_the_geometric_surface_counts_as_absent(llvm_variant, brdf):
    """The rule itself, in the surface model: with the geometric normal tilted 40 degrees
    from the shading normal (+z), f_r and the sampling pdf vanish for every direction
    below the geometric surface and are untouched above it."""
    import drjit as dr
    import mitsuba as mi

    from satsight.render.surface import SurfaceHit, SurfaceModel

    model = SurfaceModel([METAL, WHITE], RenderSettings(brdf=brdf), shading_normals=True)
    n = 4096
    rng = np.random.default_rng(1)
    wi = rng.normal(size=(n, 3))
    wi[:, 2] = np.abs(wi[:, 2])  # above the shading horizon
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.tile([0.0, 0.3, 0.954], (n, 1))
    g = np.array([math.sin(math.radians(40.0)), 0.0, math.cos(math.radians(40.0))])

    def vec(a):
        return mi.Vector3f(*(mi.Float(a[:, k].astype(np.float32)) for k in range(3)))

    part = mi.UInt32(np.arange(n) % 2)
    params = model.at(part, mi.Bool(True))
    hit = SurfaceHit(params.params, mi.Vector3f(*(float(c) for c in g)))
    plain = model.eval_parts(params, vec(wi), vec(wo))
    ruled = model.eval_parts(hit, vec(wi), vec(wo))
    below = wi @ g <= 0.0
    assert 0.2 < below.mean() < 0.5
    for a, b in zip(plain, ruled, strict=True):
        a, b = np.array(a), np.array(b)
        assert np.all(b[:, below] == 0.0) and np.any(a[:, below] > 0.0)
        np.testing.assert_array_equal(b[:, ~below], a[:, ~below])
    u = mi.Float(rng.random(n).astype(np.float32))
    u2 = mi.Point2f(*(mi.Float(rng.random(n).astype(np.float32)) for _ in range(2)))
    sampled, pdf = model.sample(hit, vec(wo), u, u2)
    dr.eval(sampled, pdf)
    lower = np.array(sampled).T @ g <= 0.0
    assert lower.any() and np.all(np.array(pdf)[lower] == 0.0)
    np.testing.assert_array_equal(np.array(model.pdf(hit, sampled, vec(wo)))[lower], 0.0)


@pytest.mark.parametrize("shading", ["flat", "smooth"])
def test_unshadowed_constant_environment_lights_a_lambert_sphere_evenly(llvm_variant, shading):
    """A constant environment L0 gives a Lambert surface E = pi L0 at every normal, so
    L = rho L0 everywhere: the per-hit SH sum at the shading normal (smooth) and the
    per-face table (flat) both return it."""
    l0 = 2.0
    coefficients = np.zeros((25, 3))
    coefficients[0] = l0 * math.sqrt(4.0 * math.pi)  # Y_00 = 1 / sqrt(4 pi)
    light = LightField(np.array([0.0, 0.0, 1.0]), 0.0, coefficients)
    mesh = dict(zip(("flat", "smooth"), _spheres(WHITE), strict=True))[shading]
    settings = RenderSettings(environment="unshadowed", bounces=0, sh_order=4)
    image = Renderer(mesh, settings, llvm_variant).render(SPHERE_CAMERA, _phase_pose(0.7), light)
    seen = image.radiance_w_m2_sr[image.object_mask]
    assert len(seen) > 10000
    np.testing.assert_allclose(seen, l0, rtol=2e-3)
