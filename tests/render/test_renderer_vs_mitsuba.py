"""satsight's renderer against Mitsuba's own ``path`` integrator: an independent oracle.

The same meshes, the same Sun (Mitsuba ``directional`` emitter of the same irradiance),
the same environment (``constant`` emitter) and equivalent built-in BSDFs (``diffuse``
for IOR-1 Lambert materials, ``roughconductor`` with GGX, alpha = R^2 and perfect-mirror
Fresnel for the GGX metallic model with base colour 1 and Smith masking), both two-sided.
Mitsuba's ``max_depth`` counts emitter-to-camera segments: satsight's ``bounces = B`` is
``max_depth = B + 2``. Both images are box-filtered over the pixel.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from builders import v_mesh
from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import TargetMesh, merge_parts
from satsight.scene.procedural import generate_satellite

E_SUN_W_M2 = 671.5
L_ENV_W_M2_SR = 8.0
SUN = np.array([0.55, -0.3, 0.78])
# Mean relative error <= 1 % on lit pixels at high sample count. Mitsuba's independent
# sampler needs ~8x the paths of satsight's stratified passes for the same per-pixel noise
# (measured: 3.2 % vs 0.6 % mean relative difference between two seeds at 512 paths).
MEAN_RELATIVE_TOLERANCE = 0.01
MITSUBA_SAMPLES = 16384
SATSIGHT_SAMPLES = 2048


def _write_obj(path, vertices, faces) -> None:
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _mitsuba_bsdf(material: Material) -> dict:
    if material.metallic == 0.0 and material.ior == 1.0:
        inner = {
            "type": "diffuse",
            "reflectance": {"type": "rgb", "value": list(material.base_color_rgb)},
        }
    elif material.metallic == 1.0 and material.base_color_rgb == (1.0, 1.0, 1.0):
        inner = {
            "type": "roughconductor",
            "material": "none",
            "distribution": "ggx",
            "alpha": material.roughness**2,
        }
    else:
        raise ValueError(f"no equivalent Mitsuba BSDF for {material}")
    return {"type": "twosided", "bsdf": inner}


def _mitsuba_render(mesh: TargetMesh, camera, cam_from_body, bounces, tmp_path, seed=0):
    import mitsuba as mi

    scene: dict = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": bounces + 2, "rr_depth": 1000},
        "sun": {
            "type": "directional",
            "direction": (-SUN / np.linalg.norm(SUN)).tolist(),
            "irradiance": {"type": "rgb", "value": [E_SUN_W_M2] * 3},
        },
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [L_ENV_W_M2_SR] * 3}},
    }
    for index in range(len(mesh.part_names)):
        faces = mesh.faces[mesh.face_part_index == index]
        used, local = np.unique(faces, return_inverse=True)
        path = tmp_path / f"part_{index}.obj"
        _write_obj(path, mesh.vertices_m[used], local.reshape(-1, 3))
        scene[f"part_{index}"] = {
            "type": "obj",
            "filename": str(path),
            "face_normals": True,
            "bsdf": _mitsuba_bsdf(mesh.part_material(index)),
        }
    body_from_cam = cam_from_body.inverse()
    to_world = np.eye(4)
    # Mitsuba's camera looks along +z with +x left and +y up; OpenCV's has +x right, +y down.
    to_world[:3, :3] = body_from_cam.R_a_from_b @ np.diag([-1.0, -1.0, 1.0])
    to_world[:3, 3] = body_from_cam.t_a_from_b_m
    scene["camera"] = {
        "type": "perspective",
        "fov_axis": "x",
        "fov": math.degrees(camera.fov_x_rad),
        "to_world": mi.ScalarTransform4f(to_world.tolist()),
        "near_clip": 0.1,
        "far_clip": 1e4,
        "film": {
            "type": "hdrfilm",
            "width": camera.width_px,
            "height": camera.height_px,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": {"type": "independent", "sample_count": MITSUBA_SAMPLES},
    }
    image = mi.render(mi.load_dict(scene), seed=seed)
    return np.asarray(image, dtype=np.float64)


def _compare(mesh, camera, cam_from_body, settings, tmp_path):
    coeffs = np.zeros((25, 3))
    coeffs[0] = L_ENV_W_M2_SR * math.sqrt(4.0 * math.pi)
    light = LightField(SUN, E_SUN_W_M2, coeffs)
    ours = Renderer(mesh, settings, "llvm_ad_rgb").render(camera, cam_from_body, light, seed=4)
    reference = _mitsuba_render(mesh, camera, cam_from_body, settings.bounces, tmp_path)
    # Lit pixels whose whole footprint is on the target: the silhouette is excluded, since
    # Mitsuba sees the constant environment behind the target where satsight's image is 0.
    inside = ndimage.binary_erosion(ours.object_mask, iterations=1)
    ref = reference[inside]
    mine = ours.radiance_w_m2_sr[inside].astype(np.float64)
    lit = ref.mean(axis=1) > 0.02 * ref.mean()
    assert lit.sum() > 150
    relative = np.abs(mine[lit] - ref[lit]) / ref[lit]
    ratio_of_means = mine[lit].mean(axis=0) / ref[lit].mean(axis=0)
    return float(relative.mean()), ratio_of_means


def _lambert(name, rgb) -> Material:
    return Material(name, rgb, metallic=0.0, roughness=1.0, ior=1.0)


V_CAMERA = PinholeCamera(focal_length_m=0.0125, pixel_pitch_m=15e-6, width_px=40, height_px=40)
V_POSE = look_at_cam_from_body(np.array([18.0, -9.0, 18.0]), np.array([0.7, 0.0, 0.7]))


@pytest.mark.slow
def test_lambert_v_two_bounces_matches_mitsuba_path(llvm_variant, tmp_path):
    mesh = v_mesh(_lambert("a_red", (0.8, 0.3, 0.2)), _lambert("b_white", (0.9, 0.9, 0.9)))
    settings = RenderSettings(environment="sampled", bounces=2, samples_per_pixel=SATSIGHT_SAMPLES)
    mean_relative, ratio = _compare(mesh, V_CAMERA, V_POSE, settings, tmp_path)
    assert mean_relative <= MEAN_RELATIVE_TOLERANCE, mean_relative
    np.testing.assert_allclose(ratio, 1.0, atol=0.003)


@pytest.mark.slow
def test_rough_conductor_v_matches_mitsuba_path(llvm_variant, tmp_path):
    metal = Material("mirror_metal", (1.0, 1.0, 1.0), metallic=1.0, roughness=0.6, ior=1.5)
    mesh = v_mesh(metal, _lambert("b_green", (0.3, 0.8, 0.4)))
    settings = RenderSettings(
        environment="sampled", bounces=2, samples_per_pixel=SATSIGHT_SAMPLES, ggx_masking="smith"
    )
    mean_relative, ratio = _compare(mesh, V_CAMERA, V_POSE, settings, tmp_path)
    assert mean_relative <= MEAN_RELATIVE_TOLERANCE, mean_relative
    np.testing.assert_allclose(ratio, 1.0, atol=0.003)


@pytest.mark.slow
def test_lambert_satellite_with_shadows_matches_mitsuba_path(llvm_variant, tmp_path):
    satellite = generate_satellite("two_wings_dish", seed=3)
    colours = [(0.8, 0.7, 0.3), (0.2, 0.3, 0.7), (0.9, 0.9, 0.9), (0.5, 0.5, 0.5)]
    materials = {}
    parts = []
    for index, name in enumerate(satellite.part_names):
        m = _lambert(f"lambert_{index % 4}", colours[index % 4])
        materials[m.name] = m
        faces = satellite.faces[satellite.face_part_index == index]
        parts.append((name, m.name, satellite.vertices_m, faces))
    mesh = merge_parts(parts, materials, "satellite")
    camera = PinholeCamera(focal_length_m=0.03, pixel_pitch_m=15e-6, width_px=44, height_px=44)
    pose = look_at_cam_from_body(np.array([14.0, -10.0, 9.0]) * 1.6, mesh.center_m)
    settings = RenderSettings(environment="sampled", bounces=1, samples_per_pixel=SATSIGHT_SAMPLES)
    mean_relative, ratio = _compare(mesh, camera, pose, settings, tmp_path)
    assert mean_relative <= MEAN_RELATIVE_TOLERANCE, mean_relative
    np.testing.assert_allclose(ratio, 1.0, atol=0.005)
