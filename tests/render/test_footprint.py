"""A small target's flux integrated over its pixels' area (render/footprint.py): closed
forms for Lambert plates from 0.3 m at 50 km to GEO, a satellite against its own resolved
image, and the grid's bookkeeping."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render.footprint import (
    FOOTPRINT_SAMPLES_ACROSS,
    compose_pixels,
    plan_footprint,
    projected_box_px,
)
from satsight.render.renderer import Renderer
from satsight.render.settings import DIRECT_SUN_ONLY
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts
from satsight.scene.procedural import generate_satellite

RHO = 0.5
E_SUN_W_M2 = 1000.0
L_PLATE = RHO * E_SUN_W_M2 / math.pi  # Lambert plate facing the Sun and the camera
SMALL = PinholeCamera.wide_field().with_size(96, 96)


def _plate(side_m: float):
    v, f = plate_parts(size_m=side_m)
    material = Material("lambert", (RHO, RHO, RHO), metallic=0.0, roughness=1.0, ior=1.0)
    return merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")


def _shifted(camera: PinholeCamera, rng) -> PinholeCamera:
    """The camera with its principal point moved by a random sub-pixel amount, so the
    target's image falls at a random phase within its pixel."""
    dx, dy = rng.uniform(-0.5, 0.5, size=2)
    return dataclasses.replace(camera, cx_px=camera.cx_px + dx, cy_px=camera.cy_px + dy)


def _pose(distance_m: float, rng):
    """Looking down -z at the plate from +z, rolled at random about the line of sight."""
    roll = rng.uniform(0.0, math.pi)
    return look_at_cam_from_body(
        np.array([0.0, 0.0, distance_m]), np.zeros(3), (math.sin(roll), math.cos(roll), 0.0)
    )


# Side 0.3 m at 50 km is 0.28 px across in the wide-field camera (f = 0.7 m, 15 um), 10 m
# is 9.3 px; 2 m at GEO (35 786 km) is 0.0026 px in the f = 3 m camera, far below float32's
# ~0.012 px resolution of a camera ray's direction there.
@pytest.mark.parametrize(
    ("side_m", "distance_m", "preset"),
    [(0.3, 50e3, "wide_field"), (1.0, 50e3, "wide_field"), (2.0, 50e3, "wide_field"),
     (10.0, 50e3, "wide_field"), (2.0, 35_786e3, "high_resolution")],
)  # fmt: skip
def test_a_plate_keeps_its_flux_at_any_size_in_pixels(llvm_variant, side_m, distance_m, preset):
    """Sum over pixels of radiance = L x the plate's image area in px^2 (radiance x pixel
    solid angle summed is the irradiance L A / d^2 for a small, on-axis plate): within 3 %
    for each of six random sub-pixel phases and rolls, within 1 % on average. With the
    grid's 128 cells across, the edge error is ~0.6/128 = 0.5 % (one sigma) of the area."""
    camera = getattr(PinholeCamera, preset)().with_size(64, 64)
    renderer = Renderer(_plate(side_m), DIRECT_SUN_ONLY, llvm_variant)
    light = LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_SUN_W_M2)
    rng = np.random.default_rng(int(side_m * 10 + distance_m / 1e3))
    area_px2 = side_m**2 * (camera.focal_length_px / distance_m) ** 2
    ratios = []
    plate_corners = np.array([[x, y, 0.0] for y in (-1, 1) for x in (-1, 1)]) * side_m / 2
    for seed in range(6):
        shifted, pose = _shifted(camera, rng), _pose(distance_m, rng)
        image = renderer.render(shifted, pose, light, seed=seed)
        assert image.footprint is not None and image.footprint["integrated"]
        x0, y0, x1, y1 = projected_box_px(shifted, pose, plate_corners)
        assert image.footprint["sub_pixel"] == (x1 - x0 < 1.0 and y1 - y0 < 1.0)
        ratios.append(image.radiance_w_m2_sr[..., 1].sum(dtype=np.float64) / (L_PLATE * area_px2))
    ratios = np.array(ratios)
    assert np.all(np.abs(ratios - 1.0) < 0.03), ratios
    assert abs(ratios.mean() - 1.0) < 0.01, ratios


def test_pixel_centres_alone_lose_or_multiply_a_sub_pixel_plate(llvm_variant):
    """The failure the grid removes: a 1 m plate at 50 km (0.93 px) rendered at pixel
    centres reads 0 or ~1/0.87 of its area, depending on where it falls."""
    camera = SMALL
    renderer = Renderer(_plate(1.0), DIRECT_SUN_ONLY.with_(integrate_footprint=False), llvm_variant)
    light = LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_SUN_W_M2)
    rng = np.random.default_rng(3)
    area_px2 = (camera.focal_length_px / 50e3) ** 2
    ratios = [
        renderer.render(_shifted(camera, rng), _pose(50e3, rng), light, seed=k)
        .radiance_w_m2_sr[..., 1].sum(dtype=np.float64) / (L_PLATE * area_px2)
        for k in range(8)
    ]  # fmt: skip
    assert max(abs(r - 1.0) for r in ratios) > 0.1, ratios


def test_a_satellite_far_away_sends_the_flux_of_its_resolved_image(llvm_variant):
    """The two-wing satellite (metal, film, cells; direct sunlight) seen along one direction:
    the irradiance at the camera times d^2 at 50 km, 1 000 km and 36 000 km (0.6 to
    0.0009 px across in the wide-field camera) equals that of its resolved image at 5 km in
    the f = 3 m camera (~280 px across, 4 x 4 sub-pixel positions), within 3 % each."""
    mesh = generate_satellite("two_wings", seed=2)
    light = LightField.sun_only(np.array([0.3, -0.4, 0.866]), E_SUN_W_M2)
    direction = np.array([0.5, 0.3, 0.81])
    direction /= np.linalg.norm(direction)

    def flux_times_d2(camera: PinholeCamera, distance_m: float, settings) -> float:
        pose = look_at_cam_from_body(mesh.center_m + distance_m * direction, mesh.center_m)
        image = Renderer(mesh, settings, llvm_variant).render(camera, pose, light, seed=1)
        # Near the axis every pixel's solid angle is (1 / f_px)^2 to 1e-6.
        pixel_sr = camera.focal_length_px**-2
        return (
            float(image.radiance_w_m2_sr.sum(dtype=np.float64, axis=(0, 1))[1])
            * pixel_sr
            * distance_m**2
        )

    resolved = flux_times_d2(
        PinholeCamera.high_resolution().with_size(384, 384), 5e3,
        DIRECT_SUN_ONLY.with_(supersampling=4, integrate_footprint=False),
    )  # fmt: skip
    assert resolved > 0.0
    for distance_m in (50e3, 1000e3, 36_000e3):
        far = flux_times_d2(SMALL, distance_m, DIRECT_SUN_ONLY)
        assert far == pytest.approx(resolved, rel=0.03), distance_m


def test_the_grid_puts_whole_cells_in_pixels_and_enough_across_the_target():
    camera = PinholeCamera.wide_field().with_size(64, 48)
    rng = np.random.default_rng(5)
    corners = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-1.0, 1.0) for x in (-2.0, 2.0)])
    pose = _pose(40e3, rng)
    grid = plan_footprint(camera, pose, corners, np.zeros(3), 2.3, passes_per_pixel=1)
    box = projected_box_px(camera, pose, corners)
    assert grid is not None and grid.box_xyxy_px == box
    h = grid.spacing_px[0]
    m = round(1.0 / h)
    assert m * h == pytest.approx(1.0, rel=1e-12)
    shorter = min(box[2] - box[0], box[3] - box[1])
    assert shorter / h >= FOOTPRINT_SAMPLES_ACROSS
    # Every cell lies inside the pixel it is summed into, and the cells cover the box.
    column = grid.pixel_index % camera.width_px
    row = grid.pixel_index // camera.width_px
    assert np.all(np.abs(grid.x_px - column) <= 0.5 - h / 2 + 1e-12)
    assert np.all(np.abs(grid.y_px - row) <= 0.5 - h / 2 + 1e-12)
    assert grid.x_px.min() - h / 2 <= box[0] and grid.x_px.max() + h / 2 >= box[2]
    assert grid.y_px.min() - h / 2 <= box[1] and grid.y_px.max() + h / 2 >= box[3]
    counts = np.bincount(np.searchsorted(grid.pixels, grid.pixel_index))
    assert counts.max() == m * m
    # The anchored rays are the camera's rays through the cell centres: each start projects
    # back onto its cell centre.
    body_from_cam = pose.inverse()
    start_body = grid.origin_render_m + np.zeros(3)  # render origin = the box centre, here 0
    start_cam = body_from_cam.inverse().apply(start_body)
    u = camera.focal_length_px * start_cam[:, 0] / start_cam[:, 2] + camera.cx_px
    v = camera.focal_length_px * start_cam[:, 1] / start_cam[:, 2] + camera.cy_px
    np.testing.assert_allclose(u, grid.x_px, rtol=0, atol=1e-6)
    np.testing.assert_allclose(v, grid.y_px, rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(grid.direction_body, axis=1), 1.0, atol=1e-15)


def test_no_grid_where_the_pixels_already_sample_the_target_finely():
    camera = PinholeCamera.wide_field().with_size(512, 512)
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    rng = np.random.default_rng(6)
    # 2 m across at 300 m is ~310 px: 128 cells across would be coarser than the pixels.
    assert plan_footprint(camera, _pose(300.0, rng), corners, np.zeros(3), 1.8, 1) is None
    # 2 m at 3 km (~31 px, 5 cells a pixel side): a grid, unless the frame already traces
    # more than 25 paths a pixel.
    assert plan_footprint(camera, _pose(3e3, rng), corners, np.zeros(3), 1.8, 1) is not None
    assert plan_footprint(camera, _pose(3e3, rng), corners, np.zeros(3), 1.8, 25) is None
    # Near the camera (within 4 bounding radii) or behind it: none.
    assert plan_footprint(camera, _pose(5.0, rng), corners, np.zeros(3), 1.8, 1) is None


def test_compose_conserves_flux_and_fills_the_rest_with_the_background():
    camera = PinholeCamera.wide_field().with_size(32, 32)
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    grid = plan_footprint(
        camera, _pose(200e3, np.random.default_rng(2)), corners, np.zeros(3), 1.8, 1
    )
    assert grid is not None and grid.sub_pixel
    n = grid.sample_count
    h2 = grid.spacing_px[0] * grid.spacing_px[1]
    rng = np.random.default_rng(9)
    radiance = rng.uniform(0.0, 5.0, size=(n, 3))
    black = compose_pixels(grid, radiance, None)
    np.testing.assert_allclose(black.sum(axis=0), radiance.sum(axis=0) * h2, rtol=1e-12)
    # Each pixel's cells summed one by one in their order: the same bits.
    slot = np.searchsorted(grid.pixels, grid.pixel_index)
    in_order = np.zeros((grid.pixels.size, 3))
    for k in range(n):
        in_order[slot[k]] += radiance[k]
    np.testing.assert_array_equal(black, in_order * h2)
    # Cells that see the same background as the pixel centre leave the pixel at it.
    background = np.tile([[1.0, 2.0, 3.0]], (grid.pixels.size, 1))
    uniform = compose_pixels(grid, np.tile([[1.0, 2.0, 3.0]], (n, 1)), background)
    np.testing.assert_allclose(uniform, background, rtol=1e-12)


def test_the_irradiance_label_does_not_depend_on_the_supersampling(llvm_variant):
    """``target_irradiance_w_m2`` of the satellite at 50 km (under a pixel across in the
    wide-field camera) with 1 and with 4 x 4 sub-pixel positions: within 1 %. Pixel
    centres alone gave labels from -5 % to +49 % apart."""
    from satsight.sensor.photometry import frame_photometry

    mesh = generate_satellite("two_wings", seed=2)
    light = LightField.sun_only(np.array([0.3, -0.4, 0.866]), E_SUN_W_M2)
    pose = look_at_cam_from_body(mesh.center_m + np.array([0.0, 5e4, 0.0]), mesh.center_m)
    corners = [list(p) for p in SMALL.project(pose.apply(mesh.box_keypoints_body_m[:8]))]
    weights = np.array([0.25, 0.5, 0.25])
    labels = []
    for supersampling in (1, 4):
        settings = DIRECT_SUN_ONLY.with_(supersampling=supersampling)
        image = Renderer(mesh, settings, llvm_variant).render(SMALL, pose, light, seed=2)
        assert image.footprint is not None
        photometry = frame_photometry(image, SMALL, weights, corners, E_SUN_W_M2, 1.496e11)
        labels.append(photometry["target_irradiance_w_m2"])
    assert labels[0] > 0.0
    assert labels[1] == pytest.approx(labels[0], rel=0.01)


@pytest.mark.parametrize("side_m", [0.3, 1.0, 10.0])
def test_the_detector_gets_a_small_plates_signal_through_the_optics(llvm_variant, side_m):
    """Rendered plate at 50 km through the camera's blur (the frame kernel, its negative
    lobes filled from their neighbours rather than clipped): the focal-plane irradiance
    summed over the frame is L pi tau / (4 N^2) x the plate's image area (grey plate: the
    channel weights sum to 1), within 1.5 % for each of four sub-pixel phases. The optics
    keep the flux to < 1e-5 (tests/sensor/test_convolution.py); the rest is the grid's."""
    from satsight.sensor.chain import SensorChain
    from satsight.sensor.detector import DetectorParameters
    from satsight.sensor.optics import Optics

    camera = PinholeCamera.wide_field().with_size(96, 96)
    optics = Optics.for_preset("wide_field")
    chain = SensorChain(
        camera=camera,
        optics=optics,
        detector=DetectorParameters(pixel_pitch_m=camera.pixel_pitch_m),
        band_nm=(450.0, 900.0),
    )
    renderer = Renderer(_plate(side_m), DIRECT_SUN_ONLY, llvm_variant)
    light = LightField.sun_only(np.array([0.0, 0.0, 1.0]), E_SUN_W_M2)
    rng = np.random.default_rng(int(10 * side_m))
    area_px2 = side_m**2 * (camera.focal_length_px / 50e3) ** 2
    per_radiance = (
        math.pi
        * optics.transmission
        * (1.0 - optics.obscuration_ratio**2)
        / (4.0 * optics.f_number**2)
    )
    for seed in range(4):
        image = renderer.render(
            _shifted(camera, rng), _pose(50e3, rng), light, seed=seed, margin_px=chain.margin_px
        )
        focal = chain.focal_plane_irradiance_w_m2(image).sum(dtype=np.float64)
        assert focal / (L_PLATE * per_radiance * area_px2) == pytest.approx(1.0, abs=0.015)


@pytest.mark.parametrize("samples_per_pixel", [1, 4])
@pytest.mark.parametrize("earth_behind", [False, True])
def test_a_frame_with_a_grid_traces_only_labels_and_bodies_for_its_pixels(
    llvm_variant, monkeypatch, samples_per_pixel, earth_behind
):
    """With a footprint grid, the frame's own passes leave out the light of the target's
    surfaces (the grid's pixels, the only ones that can see the target, get the grid's
    radiance): the bytes are those of a render that shades every pass, the Earth behind
    the target included; the path tracer runs only on the grid's cells."""
    from satsight.lighting.scene_bodies import earth_body
    from satsight.render.settings import RenderSettings

    mesh = generate_satellite("two_wings", seed=2)
    settings = RenderSettings(
        bounces=1, environment="unshadowed", samples_per_pixel=samples_per_pixel
    )
    renderer = Renderer(mesh, settings, llvm_variant)
    camera = PinholeCamera.wide_field().with_size(160, 120)
    direction = np.array([0.5, 0.3, 0.81]) / np.linalg.norm([0.5, 0.3, 0.81])
    camera_body = mesh.center_m + 15e3 * direction  # about 30 px across
    pose = look_at_cam_from_body(camera_body, mesh.center_m)
    sun = np.array([0.3, -0.4, 0.866])
    light = LightField.sun_only(sun, E_SUN_W_M2)
    if earth_behind:  # the camera 500 km above a sphere behind the target
        earth = earth_body(camera_body - 6_871e3 * direction, np.eye(3), 0.3, sun, E_SUN_W_M2,
                           shape="sphere")  # fmt: skip
        light = LightField(sun, E_SUN_W_M2, np.zeros((25, 3)), bodies=(earth,))
    traced = []
    tracer = renderer._path_tracer
    original_trace = type(tracer).trace.__get__(tracer)
    monkeypatch.setattr(tracer, "trace", lambda *a: traced.append(1) or original_trace(*a))
    image = renderer.render(camera, pose, light, seed=3, margin_px=4)
    assert image.footprint is not None
    grid_traces = len(traced)
    original_passes = Renderer._radiance_passes.__get__(renderer)
    monkeypatch.setattr(
        renderer,
        "_radiance_passes",
        lambda *a, **k: original_passes(*a, **{**k, "shade": True}),
    )
    traced.clear()
    shaded = renderer.render(camera, pose, light, seed=3, margin_px=4)
    assert len(traced) > grid_traces  # the frame's passes traced paths only here
    assert np.array_equal(image.radiance_w_m2_sr, shaded.radiance_w_m2_sr)
    assert np.array_equal(image.margin_radiance_w_m2_sr, shaded.margin_radiance_w_m2_sr)
    for name in ("depth_m", "part_id", "normals_cam", "background_id"):
        assert np.array_equal(getattr(image, name), getattr(shaded, name)), name
    assert image.object_mask.sum() > 20
    if earth_behind:
        assert (image.background_mask() == 1).sum() > 1000
