"""Depth, masks and pose labels against independent computations.

Oracle: trimesh's Embree ray caster (embreex) traces the same pixel-centre rays in its own
code; depth is then recomputed in float64 from the triangle it reports.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from scipy.ndimage import binary_dilation
from scipy.spatial.transform import Rotation

from satsight.camera.pinhole import PinholeCamera
from satsight.dataset.labels import frame_labels
from satsight.lighting.light_field import LightField, SunLight
from satsight.poses.views import View
from satsight.render.direct import DirectRenderer
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.procedural import generate_satellite
from tolerances import MICRO_PX, ONE_MM

AGREEMENT_FRACTION = 0.999
SUN = SunLight(np.array([0.4, -0.3, 0.85]), 671.5)


@pytest.fixture(scope="module")
def satellite():
    return generate_satellite("two_wings_dish", seed=11)


@pytest.fixture(scope="module")
def renderer(satellite, llvm_variant):
    return DirectRenderer(satellite, llvm_variant)


def _camera_for(mesh, distance_m: float, side_px: int) -> PinholeCamera:
    """Optics that make the target's bounding sphere span ~80 % of a square image."""
    pitch = 15e-6
    focal = 0.8 * side_px * pitch * distance_m / (2.0 * mesh.bounding_radius_m)
    return PinholeCamera(focal, pitch, side_px, side_px)


def _oracle(mesh, camera, cam_from_body):
    """Per-pixel (triangle index, depth along +z) from trimesh + Embree, float64 geometry."""
    tm = trimesh.Trimesh(mesh.vertices_m, mesh.faces, process=False)
    intersector = trimesh.ray.ray_pyembree.RayMeshIntersector(tm)
    v, u = np.mgrid[0 : camera.height_px, 0 : camera.width_px]
    pixels = np.stack([u, v], -1).reshape(-1, 2).astype(np.float64)
    d_cam = camera.ray_directions_cam(pixels)
    body_from_cam = cam_from_body.inverse()
    d_body = body_from_cam.rotate(d_cam)
    # Embree works in float32: start the rays (in float64) 1.5 bounding radii before the
    # target centre so its hit distances are small and keep millimetre precision.
    camera_body = body_from_cam.t_a_from_b_m
    t_start = np.linalg.norm(camera_body - mesh.center_m) - 1.5 * mesh.bounding_radius_m
    origin = camera_body + t_start * d_body
    tri = intersector.intersects_first(origin, d_body)
    depth = np.zeros(len(tri))
    hit = tri >= 0
    v0 = mesh.vertices_m[mesh.faces[tri[hit], 0]]
    e1 = mesh.vertices_m[mesh.faces[tri[hit], 1]] - v0
    e2 = mesh.vertices_m[mesh.faces[tri[hit], 2]] - v0
    n = np.cross(e1, e2)
    t = np.einsum("ij,ij->i", v0 - origin[hit], n) / np.einsum("ij,ij->i", d_body[hit], n)
    depth[hit] = (t_start + t) * d_cam[hit, 2]
    shape = (camera.height_px, camera.width_px)
    return tri.reshape(shape), depth.reshape(shape)


@pytest.mark.parametrize(
    ("distance_m", "azimuth_deg", "elevation_deg"),
    [(1000.0, 30.0, 20.0), (1000.0, 200.0, -40.0), (150e3, 100.0, 60.0)],
)
def test_depth_and_masks_match_embree_oracle(
    satellite, renderer, distance_m, azimuth_deg, elevation_deg
):
    camera = _camera_for(satellite, distance_m, 240)
    view = View(distance_m, math.radians(azimuth_deg), math.radians(elevation_deg), 0.3)
    cam_from_body = view.cam_from_body(satellite.center_m)
    image = renderer.render(camera, cam_from_body, SUN)
    tri, depth_ref = _oracle(satellite, camera, cam_from_body)

    mask_ref = tri >= 0
    assert mask_ref.sum() > 3000  # thousands of target pixels are compared
    assert np.mean(image.object_mask == mask_ref) >= AGREEMENT_FRACTION

    part_ref = np.where(mask_ref, satellite.part_ids[np.maximum(tri, 0)], 0)
    assert np.mean(image.part_id == part_ref) >= AGREEMENT_FRACTION

    # Depth along a ray that grazes a surface is ill-conditioned: a lateral difference dx
    # between two casters' rays moves the hit by dx / cos(incidence). Compare where the
    # incidence cosine is >= 0.1 (incidence < 84 deg); that is nearly every pixel.
    v, u = np.mgrid[0 : camera.height_px, 0 : camera.width_px]
    rays = camera.ray_directions_cam(np.stack([u, v], -1).reshape(-1, 2).astype(np.float64))
    cos_incidence = np.abs(np.einsum("ijk,ijk->ij", image.normals_cam, rays.reshape((*v.shape, 3))))
    # Pixels where the casters saw different parts (counted above) are not depth-compared.
    both = image.object_mask & mask_ref & (image.part_id == part_ref)
    well_posed = both & (cos_incidence >= 0.1)
    assert well_posed.sum() >= 0.95 * both.sum()
    depth_error = np.abs(image.depth_m[well_posed].astype(np.float64) - depth_ref[well_posed])
    # Depth is float32: allow 1 mm at 1 km, and the same relative precision further out.
    tolerance = ONE_MM * distance_m / 1000.0
    assert np.mean(depth_error <= tolerance) >= AGREEMENT_FRACTION
    assert np.all(image.depth_m[~image.object_mask] == 0.0)


@pytest.mark.parametrize("radiative", [False, True])
def test_part_ids_at_an_odd_image_size_match_embree_oracle(satellite, llvm_variant, radiative):
    """Odd width and height (part ids are handed over two per 32-bit word), through both
    label paths: the direct-sun renderer's single kernel and the radiative renderer's
    first (hit-finding) kernel."""
    settings = RenderSettings(environment="unshadowed", bounces=1)
    renderer = Renderer(satellite, settings, llvm_variant) if radiative else None
    renderer = renderer or DirectRenderer(satellite, llvm_variant)
    pitch = 15e-6
    camera = PinholeCamera(
        0.8 * 97 * pitch * 1000.0 / (2.0 * satellite.bounding_radius_m), pitch, 121, 97
    )
    cam_from_body = View(1000.0, math.radians(40.0), math.radians(15.0), 0.2).cam_from_body(
        satellite.center_m
    )
    if radiative:
        light = LightField.sun_only(SUN.direction_body, SUN.irradiance_w_m2)
        image = renderer.render(camera, cam_from_body, light)
    else:
        image = renderer.render(camera, cam_from_body, SUN)
    tri, _ = _oracle(satellite, camera, cam_from_body)
    part_ref = np.where(tri >= 0, satellite.part_ids[np.maximum(tri, 0)], 0)
    assert image.part_id.dtype == np.uint16
    assert image.part_id.shape == (97, 121)
    assert (part_ref > 0).sum() > 600
    assert np.mean(image.part_id == part_ref) >= AGREEMENT_FRACTION
    # The last pixel (the unpaired half of the last word) is background in both.
    assert image.part_id[-1, -1] == part_ref[-1, -1]


def test_depth_valid_at_200_km(satellite, renderer):
    """Depth stays exact to float32 precision with the camera 200 km away."""
    camera = _camera_for(satellite, 200e3, 64)
    cam_from_body = View(200e3, 0.4, 0.2).cam_from_body(satellite.center_m)
    image = renderer.render(camera, cam_from_body, SUN)
    tri, depth_ref = _oracle(satellite, camera, cam_from_body)
    both = image.object_mask & (tri >= 0)
    assert both.sum() > 300
    relative = np.abs(image.depth_m[both] - depth_ref[both]) / depth_ref[both]
    assert np.median(relative) < 1e-6
    assert np.all((image.depth_m[both] > 199.9e3) & (image.depth_m[both] < 200.1e3))


def _render_with_labels(satellite, renderer, view: View, side_px: int = 256):
    camera = _camera_for(satellite, view.distance_m, side_px)
    cam_from_body = view.cam_from_body(satellite.center_m)
    image = renderer.render(camera, cam_from_body, SUN)
    return camera, image, frame_labels(satellite, camera, cam_from_body, SUN, image)


def test_vertices_reproject_inside_object_mask(satellite, renderer):
    view = View(2000.0, math.radians(-60.0), math.radians(35.0), math.radians(15.0))
    camera, image, labels = _render_with_labels(satellite, renderer, view)
    R = Rotation.from_quat(labels["q_cam_from_body"], scalar_first=True).as_matrix()
    points_cam = satellite.vertices_m @ R.T + np.array(labels["t_cam_from_body_m"])
    K = np.array(labels["K"])
    uvw = points_cam @ K.T
    uv = uvw[:, :2] / uvw[:, 2:]
    pix = np.rint(uv).astype(int)
    inside = (
        (pix[:, 0] >= 0)
        & (pix[:, 0] < camera.width_px)
        & (pix[:, 1] >= 0)
        & (pix[:, 1] < camera.height_px)
    )
    assert inside.all()
    # A vertex on the silhouette can fall in a pixel whose centre ray just misses: 1 px slack.
    grown = binary_dilation(image.object_mask, iterations=1)
    assert grown[pix[:, 1], pix[:, 0]].all()


def test_keypoints_equal_independent_projection(satellite, renderer):
    view = View(5000.0, math.radians(120.0), math.radians(-10.0), math.radians(-40.0))
    _, _, labels = _render_with_labels(satellite, renderer, view, side_px=128)
    R = Rotation.from_quat(labels["q_cam_from_body"], scalar_first=True).as_matrix()
    b = satellite.bounds_m
    corners = np.array([[x, y, z] for z in b[:, 2] for y in b[:, 1] for x in b[:, 0]])
    keypoints_body = np.vstack([corners, b.mean(axis=0)])
    p = keypoints_body @ R.T + np.array(labels["t_cam_from_body_m"])
    K = np.array(labels["K"])
    expected = np.stack(
        [K[0, 0] * p[:, 0] / p[:, 2] + K[0, 2], K[1, 1] * p[:, 1] / p[:, 2] + K[1, 2]], -1
    )
    np.testing.assert_allclose(np.array(labels["keypoints_px"]), expected, atol=MICRO_PX, rtol=0)
    np.testing.assert_allclose(labels["keypoints_depth_m"], p[:, 2], rtol=1e-12)


def test_labels_describe_the_frame(satellite, renderer):
    view = View(3000.0, 0.7, 0.3)
    camera, image, labels = _render_with_labels(satellite, renderer, view)
    q = np.array(labels["q_cam_from_body"])
    assert q[0] >= 0 and abs(np.linalg.norm(q) - 1.0) < 1e-12
    assert labels["image_size_px"] == [camera.width_px, camera.height_px]
    assert labels["range_to_center_m"] == pytest.approx(3000.0, rel=1e-12)
    x0, y0, x1, y1 = labels["bbox_xyxy_px"]
    ys, xs = np.nonzero(image.object_mask)
    assert (x0, y0, x1, y1) == (xs.min(), ys.min(), xs.max(), ys.max())
    assert labels["visible_pixel_fraction"] == pytest.approx(image.object_mask.mean())
    sun_cam = np.array(labels["sun_direction_cam"])
    R = Rotation.from_quat(q, scalar_first=True).as_matrix()
    np.testing.assert_allclose(sun_cam, R @ SUN.direction_body, atol=1e-12)
    # phase angle: Sun-target-camera angle
    to_cam = -(R @ satellite.center_m + labels["t_cam_from_body_m"])
    cos_phase = to_cam @ sun_cam / np.linalg.norm(to_cam)
    assert labels["phase_angle_deg"] == pytest.approx(math.degrees(math.acos(cos_phase)), abs=1e-9)


def test_supersampling_keeps_labels_and_converges(satellite, llvm_variant):
    """Labels come from pixel centres whatever the supersampling; the pixel-averaged
    radiance converges towards a dense reference as the sub-pixel grid gets finer (the
    footprint grid, which would replace the target's pixels here, off)."""
    renderer = DirectRenderer(satellite, llvm_variant)
    renderer.settings = renderer.settings.with_(integrate_footprint=False)
    view = View(1500.0, 1.0, 0.4)
    camera = _camera_for(satellite, view.distance_m, 96)
    cam_from_body = view.cam_from_body(satellite.center_m)
    images = {s: renderer.render(camera, cam_from_body, SUN, supersampling=s) for s in (1, 2, 4, 8)}
    for s in (2, 4, 8):
        np.testing.assert_array_equal(images[1].part_id, images[s].part_id)
        np.testing.assert_array_equal(images[1].depth_m, images[s].depth_m)
    reference = images[8].radiance_w_m2_sr
    errors = [np.abs(images[s].radiance_w_m2_sr - reference).mean() for s in (1, 2, 4)]
    assert errors[0] > errors[1] > errors[2] > 0.0
    # Reflected power is conserved by the box filter to within the edge aliasing.
    assert images[4].radiance_w_m2_sr.sum() == pytest.approx(reference.sum(), rel=0.02)


def test_mesh_modelled_far_from_its_origin_renders_like_a_centred_one(satellite, llvm_variant):
    """A mesh whose vertices sit 5 km from its own origin (CAD files do this) renders the
    same depth, masks and radiance as the same mesh centred: the renderer works about the
    bounding-box centre, so float32 keeps its precision."""
    from satsight.scene.mesh import TargetMesh

    offset = np.array([5000.0, -3000.0, 1200.0])
    far = TargetMesh(
        satellite.vertices_m + offset,
        satellite.faces,
        satellite.face_part_index,
        satellite.part_names,
        satellite.part_materials,
        satellite.materials,
        name="far",
    )
    view = View(800.0, 0.6, 0.35, 0.2)
    camera = _camera_for(satellite, view.distance_m, 160)
    near_image = DirectRenderer(satellite, llvm_variant).render(
        camera, view.cam_from_body(satellite.center_m), SUN
    )
    far_image = DirectRenderer(far, llvm_variant).render(
        camera, view.cam_from_body(far.center_m), SUN
    )
    assert near_image.object_mask.sum() > 2000
    assert np.mean(near_image.part_id == far_image.part_id) >= AGREEMENT_FRACTION
    both = near_image.object_mask & far_image.object_mask
    np.testing.assert_allclose(far_image.depth_m[both], near_image.depth_m[both], atol=ONE_MM)
    same = (near_image.part_id == far_image.part_id)[..., None]
    diff = np.abs(far_image.radiance_w_m2_sr - near_image.radiance_w_m2_sr)
    assert (
        np.mean(
            diff[np.broadcast_to(same, diff.shape)]
            < 1e-3 + 1e-4 * near_image.radiance_w_m2_sr[np.broadcast_to(same, diff.shape)]
        )
        >= 0.999
    )


def test_keypoints_behind_the_camera_are_null_and_labels_stay_json(satellite, renderer):
    """With the camera inside the bounding box some corners are behind it: no projection."""
    import json

    view = View(0.6 * satellite.bounding_radius_m, 0.3, 0.1)
    camera = _camera_for(satellite, 100.0, 64)
    cam_from_body = view.cam_from_body(satellite.center_m)
    image = renderer.render(camera, cam_from_body, SUN)
    labels = frame_labels(satellite, camera, cam_from_body, SUN, image)
    behind = np.array(labels["keypoints_depth_m"]) <= 0
    assert behind.any()
    assert all((kp is None) == b for kp, b in zip(labels["keypoints_px"], behind, strict=True))
    json.dumps(labels, allow_nan=False)  # raises on NaN


def test_pose_with_the_target_behind_the_camera_is_refused(satellite, renderer):
    from satsight.errors import SatsightError
    from satsight.frames.rigid import RigidTransform

    camera = _camera_for(satellite, 1000.0, 32)
    behind = RigidTransform(np.eye(3), -satellite.center_m + np.array([0.0, 0.0, -50.0]))
    with pytest.raises(SatsightError, match="behind the camera"):
        renderer.render(camera, behind, SUN)
