"""Sampling the sunlit target as a light source of inter-reflection
(``satsight.render.sunlit_surfaces``): the sampler's distribution, the closed form of a
shaded plate lit only by a sunlit one, the noise it removes and the mean it keeps."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from builders import plate_parts, v_mesh, view_integral_to_b
from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.render.sunlit_surfaces import SunlitSurfaces, part_reflectance
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts
from satsight.scene.procedural import generate_satellite

E_SUN_W_M2 = 671.5
RHO_A = (0.6, 0.4, 0.8)
RHO_B = (0.9, 0.7, 0.5)
# Four standard deviations: a false alarm about once in 16 000 checks.
Z_LIMIT = 4.0
# The Sun lights plate B (x = 0, normal +x, facing A) and only the underside of plate A
# (z = 0, normal +z): the camera above A sees light that B reflects, nothing else. A
# shades B below z = 2 x 0.3 (the Sun's rays from there meet A within x < 2).
SUN_BELOW_A = np.array([1.0, 0.0, -0.3]) / math.hypot(1.0, 0.3)
B_LIT_ABOVE_Z_M = 0.6
V_CAMERA = PinholeCamera(focal_length_m=0.02, pixel_pitch_m=15e-6, width_px=96, height_px=96)
V_POSE = look_at_cam_from_body(
    30.0 * np.array([1.0, 0.3, 1.0]) / np.linalg.norm([1.0, 0.3, 1.0]), np.array([0.7, 0.0, 0.7])
)


def _lambert_v():
    return v_mesh(
        Material("a_lambert", RHO_A, metallic=0.0, roughness=1.0, ior=1.0),
        Material("b_lambert", RHO_B, metallic=0.0, roughness=1.0, ior=1.0),
    )


def _settings(**changes) -> RenderSettings:
    return RenderSettings(environment="off", bounces=1, **changes)


def test_face_choice_and_point_follow_the_reflected_sunlight(llvm_variant):
    """Faces are drawn with probability area x reflectance x |cos(sun, normal)| (chi-square
    over 60 000 draws) and points are uniform on their triangle (mean barycentrics 1/3);
    the density per unit area integrates to 1 over the faces."""
    import mitsuba as mi

    white = Material("white", (0.9, 0.9, 0.9), 0.0, 1.0, 1.5)
    gold = Material("gold", (0.9, 0.6, 0.2), 1.0, 0.3, 1.5)
    area = np.array([1.0, 2.0, 0.5, 3.0, 1.5])
    normal = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0], [0.6, 0, 0.8]], dtype=float)
    part = np.array([0, 1, 0, 1, 0])
    sun = np.array([0.48, 0.0, 0.8]) / np.linalg.norm([0.48, 0.0, 0.8])
    sunlit = SunlitSurfaces(area, normal, part, [white, gold])
    reflectance = np.array([part_reflectance(white), part_reflectance(gold)])[part]
    expected = area * reflectance * np.abs(normal @ sun)
    expected /= expected.sum()
    assert expected[3] == 0.0  # edge-on to the Sun: never drawn

    tables = sunlit.frame_tables(sun)
    pdf_area = tables.pdf_area_per_m2.numpy()
    np.testing.assert_allclose((pdf_area * area).sum(), 1.0, rtol=1e-6)
    np.testing.assert_allclose(pdf_area * area, expected, rtol=1e-5, atol=1e-7)

    n = 60_000
    rng = np.random.default_rng(4)
    u = [mi.Float(rng.random(n, dtype=np.float32)) for _ in range(3)]
    face, bary_u, bary_v, pdf = SunlitSurfaces.sample(tables, *u)
    face = face.numpy()
    counts = np.bincount(face, minlength=len(area))
    assert counts[3] == 0
    drawn = expected > 0
    assert stats.chisquare(counts[drawn], n * expected[drawn]).pvalue > 1e-4
    np.testing.assert_allclose(pdf.numpy(), pdf_area[face], rtol=1e-6)
    b1, b2 = bary_u.numpy(), bary_v.numpy()
    assert np.all((b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1.0 + 1e-6))
    se = math.sqrt(1.0 / 18.0 / n)  # variance of a barycentric of a uniform point: 1/18
    assert abs(b1.mean() - 1 / 3) < Z_LIMIT * se
    assert abs(b2.mean() - 1 / 3) < Z_LIMIT * se
    # No reflected sunlight at all: no tables.
    assert (
        SunlitSurfaces(area, normal, part, [white, gold]).frame_tables(np.array([0, 0, 0.0]))
        is None
    )


def test_face_probabilities_are_those_of_the_kernels_uniform_numbers(llvm_variant):
    """Face i is drawn where u < cdf_i and u is a multiple of 2^-23 (PCG32): the stated
    probabilities equal the share of all 2^23 values of u that pick each face, exactly,
    also for the tiny faces of a 50 000-face mesh with weights over six decades."""
    rng = np.random.default_rng(2)
    n = 50_000
    area = 10.0 ** rng.uniform(-3.0, 3.0, n)
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    white = Material("white", (0.9, 0.9, 0.9), 0.0, 1.0, 1.5)
    tables = SunlitSurfaces(area, normal, np.zeros(n, int), [white]).frame_tables(
        np.array([0.0, 0.0, 1.0])
    )
    cdf = tables.cdf.numpy()
    steps = 2**23
    u = (np.arange(steps, dtype=np.float64) / steps).astype(np.float32)
    counts = np.bincount(np.searchsorted(cdf, u, side="right"), minlength=n)
    pmf = tables.pdf_area_per_m2.numpy().astype(np.float64) * area
    np.testing.assert_allclose(pmf, counts / steps, rtol=1e-6, atol=1e-12)
    assert counts.sum() == steps


def _plate_a_points(image):
    """Pixels on plate A away from its edges, and their points in the body frame."""
    v, u = np.nonzero(image.part_id == 1)
    points_cam = V_CAMERA.backproject(np.stack([u, v], axis=1).astype(float), image.depth_m[v, u])
    points = V_POSE.inverse().apply(points_cam)
    inside = (points[:, 0] > 0.05) & (points[:, 0] < 1.95) & (np.abs(points[:, 1]) < 0.95)
    return v[inside], u[inside], points[inside]


@pytest.mark.parametrize("light_samples", [1, 4])
def test_shaded_plate_lit_by_a_sunlit_plate_matches_closed_form(llvm_variant, light_samples):
    """Plate A in B's light only: L_A = rho_A / pi x integral over B's sunlit part of
    cos cos / r^2 dA x L_B (scipy quadrature), within the seeds' own spread (the sum over
    the pixels within 4 standard errors, about 1 % here: 0.28 relative standard deviation
    per pixel at 16 paths and one light sample, 2 x 120 pixels)."""
    passes = 16
    settings = _settings(samples_per_pixel=passes, light_samples=light_samples)
    renderer = Renderer(_lambert_v(), settings, llvm_variant)
    light = LightField.sun_only(SUN_BELOW_A, E_SUN_W_M2)
    images = [renderer.render(V_CAMERA, V_POSE, light, seed=s) for s in (21, 22)]
    v, u, points = _plate_a_points(images[0])
    step = max(1, len(points) // 120)
    v, u, points = v[::step], u[::step], points[::step]
    assert len(points) > 80
    l_b = np.array(RHO_B) * E_SUN_W_M2 * float(SUN_BELOW_A[0]) / math.pi
    view = np.array([view_integral_to_b(px, py, B_LIT_ABOVE_Z_M) for px, py, _ in points])
    expected = np.array(RHO_A) / math.pi * view[:, None] * l_b
    rendered = np.stack([im.radiance_w_m2_sr[v, u] for im in images]).astype(np.float64)
    mean = rendered.mean(axis=0)
    # Per-pixel variance of the two-seed mean from the seeds' difference (unbiased).
    variance = np.square(rendered[0] - rendered[1]) / 4.0
    z_total = (mean - expected).sum(axis=0) / np.sqrt(variance.sum(axis=0))
    assert np.all(np.abs(z_total) < Z_LIMIT), z_total
    relative = np.abs((mean - expected).mean(axis=0)) / expected.mean(axis=0)
    assert np.all(relative < 0.03), relative  # a gross error, whatever the spread


def test_sampling_the_sunlit_plate_cuts_the_noise_and_keeps_the_mean(llvm_variant):
    """At one path per pixel the shaded plate's per-pixel variance drops more than 3-fold
    with one light sample (measured 6.2x) and more than 2-fold again with four (measured
    3.1x), and the mean stays within the seeds' standard error of the bounce ray's
    alone."""
    light = LightField.sun_only(SUN_BELOW_A, E_SUN_W_M2)
    results = {}
    for name, changes in {
        "off": {"sunlit_sampling": False},
        "one": {"light_samples": 1},
        "four": {"light_samples": 4},
    }.items():
        renderer = Renderer(_lambert_v(), _settings(**changes), llvm_variant)
        images = [renderer.render(V_CAMERA, V_POSE, light, seed=s) for s in range(1, 9)]
        v, u, _ = _plate_a_points(images[0])
        values = np.stack([im.radiance_w_m2_sr[v, u] for im in images]).astype(np.float64)
        results[name] = values.mean(axis=2)  # (seeds, pixels), channel mean
    variance = {name: values.var(axis=0, ddof=1).mean() for name, values in results.items()}
    assert variance["one"] < variance["off"] / 3.0, variance
    assert variance["four"] < variance["one"] / 2.0, variance
    means = {name: values.mean() for name, values in results.items()}
    # Standard error of each mean over seeds x pixels (pixels independent).
    se = {name: math.sqrt(v.var(ddof=1) / v.size) for name, v in results.items()}
    for name in ("one", "four"):
        assert abs(means[name] - means["off"]) < Z_LIMIT * math.hypot(se[name], se["off"])


@pytest.mark.slow
def test_same_mean_on_a_textured_smooth_satellite(llvm_variant):
    """Normal maps, smooth normals, the terminator lift and glossy metals: the target's
    inter-reflected light (two bounces, less the direct light) with and without sampling
    the sunlit parts agrees within 4 standard errors of four seeds each."""
    mesh = generate_satellite("two_wings_dish", seed=7, smooth_normals=True, textures=True)
    camera = PinholeCamera(focal_length_m=0.004, pixel_pitch_m=15e-6, width_px=96, height_px=96)
    pose = look_at_cam_from_body(np.array([30.0, -25.0, 12.0]), mesh.center_m)
    sun = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
    light = LightField.sun_only(sun, E_SUN_W_M2)

    def sums(**changes) -> np.ndarray:
        settings = RenderSettings(
            environment="off", samples_per_pixel=16, integrate_footprint=False, **changes
        )
        renderer = Renderer(mesh, settings, llvm_variant)
        images = [renderer.render(camera, pose, light, seed=s) for s in range(30, 34)]
        assert images[0].object_mask.sum() > 400
        return np.array([im.radiance_w_m2_sr.sum() for im in images], dtype=np.float64)

    direct = sums(bounces=0).mean()
    indirect = {on: sums(sunlit_sampling=on) - direct for on in (True, False)}
    assert indirect[False].mean() > 0.02 * direct  # there is inter-reflected light
    difference = indirect[True].mean() - indirect[False].mean()
    se = math.hypot(*(math.sqrt(v.var(ddof=1) / len(v)) for v in indirect.values()))
    assert abs(difference) < Z_LIMIT * se, (difference, se)


def test_off_for_transparent_targets_and_validated(llvm_variant):
    """A target with a partly transparent part renders the same bytes either way (the
    sampling needs opaque surfaces); the setting is a bool."""
    glassy = Material("glassy", RHO_A, metallic=0.0, roughness=1.0, ior=1.0, alpha=0.5)
    white = Material("white", RHO_B, metallic=0.0, roughness=1.0, ior=1.0)
    a_vertices, faces = plate_parts(size_m=2.0, z_m=0.0)
    b_vertices = a_vertices[:, [2, 1, 0]] + np.array([-1.0, 0.0, 1.0])  # x = -1, normal +x
    mesh = merge_parts(
        [("a", "glassy", a_vertices, faces), ("b", "white", b_vertices, faces)],
        {"glassy": glassy, "white": white},
        "v_glassy",
    )
    light = LightField.sun_only(SUN_BELOW_A, E_SUN_W_M2)
    images = [
        Renderer(mesh, _settings(sunlit_sampling=on), llvm_variant).render(
            V_CAMERA, V_POSE, light, seed=3
        )
        for on in (True, False)
    ]
    assert images[0].radiance_w_m2_sr.any()
    np.testing.assert_array_equal(images[0].radiance_w_m2_sr, images[1].radiance_w_m2_sr)
    with pytest.raises(SatsightError, match="sunlit_sampling must be true or false"):
        RenderSettings(sunlit_sampling=1)
    with pytest.raises(SatsightError, match=r"light_samples must be an integer in \[1, 64\]"):
        RenderSettings(light_samples=0)
