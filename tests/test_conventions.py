"""One test per convention of docs/conventions.md that can be checked at this level.

These are the convention statements themselves; the detailed behaviour is tested in
tests/frames/ and tests/camera/.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation

from satsight.camera.pinhole import PinholeCamera
from satsight.config.outputs import OutputsConfig
from satsight.dataset.frame_files import FrameArrays, write_frame_files
from satsight.dataset.image_files import read_exr
from satsight.frames.quaternion import (
    canonical_quaternion,
    matrix_from_quaternion,
    quaternion_from_axis_angle,
    quaternion_from_matrix,
    quaternion_multiply,
    rotate_vectors,
)
from satsight.frames.rigid import RigidTransform, look_at_cam_from_body
from satsight.render.buffers import RadianceImage
from satsight.scene.mesh import TargetMesh
from satsight.sensor.chain import DnImage

ATOL = 1e-12
ATOL_PX = 1e-9

# A small camera keeps the numbers readable: 8 x 6 pixels, centre (3.5, 2.5), f/p = 1000 px.
CAMERA = PinholeCamera(focal_length_m=0.01, pixel_pitch_m=10e-6, width_px=8, height_px=6)


def test_units_are_si_and_names_carry_them() -> None:
    fields = {f.name for f in dataclasses.fields(PinholeCamera)}
    assert fields == {"focal_length_m", "pixel_pitch_m", "width_px", "height_px", "cx_px", "cy_px"}
    camera = PinholeCamera.high_resolution()
    # Metres inside: 3 m, 15 um = 15e-6 m (not 3000 mm, not 15 um).
    assert camera.focal_length_m == 3.0
    assert camera.pixel_pitch_m == 15e-6
    # Angles in radians: a 1.17-degree field of view is 0.0205 rad.
    assert camera.fov_x_rad == pytest.approx(math.radians(1.1734), abs=1e-6)
    assert RigidTransform.identity().t_a_from_b_m.shape == (3,)


def test_transform_names_cancel_when_composed() -> None:
    # x_a = R_a_from_b @ x_b + t_a_from_b_m, and a_from_b @ b_from_c = a_from_c.
    a_from_b = RigidTransform(matrix_from_quaternion([0.9, 0.1, -0.3, 0.2]), [1.0, 2.0, 3.0])
    b_from_c = RigidTransform(matrix_from_quaternion([0.5, 0.5, 0.5, -0.5]), [-4.0, 0.0, 0.5])
    x_c = np.array([0.3, -0.7, 2.0])
    x_b = b_from_c.R_a_from_b @ x_c + b_from_c.t_a_from_b_m
    x_a = a_from_b.R_a_from_b @ x_b + a_from_b.t_a_from_b_m
    a_from_c = a_from_b @ b_from_c
    np.testing.assert_allclose(a_from_c.apply(x_c), x_a, atol=ATOL)
    np.testing.assert_allclose(a_from_c.inverse().apply(x_a), x_c, atol=ATOL)


def test_quaternions_are_scalar_first() -> None:
    np.testing.assert_array_equal(RigidTransform.identity().q_a_from_b, [1.0, 0.0, 0.0, 0.0])
    angle_rad = 0.8
    q = quaternion_from_axis_angle([0.0, 0.0, 1.0], angle_rad)
    np.testing.assert_allclose(q, [math.cos(angle_rad / 2), 0, 0, math.sin(angle_rad / 2)])
    # To SciPy: scalar_first=True. To scalar-last [qx, qy, qz, qw] (SciPy's default, ROS,
    # Eigen's coeffs()): np.roll(q, -1).
    rotation = Rotation.from_quat(q, scalar_first=True)
    np.testing.assert_allclose(rotation.as_matrix(), matrix_from_quaternion(q), atol=ATOL)
    np.testing.assert_allclose(
        Rotation.from_quat(np.roll(q, -1)).as_matrix(), matrix_from_quaternion(q), atol=ATOL
    )


def test_quaternion_product_is_hamilton() -> None:
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_array_equal(quaternion_multiply(i, j), k)  # JPL would give -k
    # q_a_from_c = q_a_from_b * q_b_from_c, as R_a_from_c = R_a_from_b @ R_b_from_c.
    q_a_from_b = quaternion_from_axis_angle([1.0, 0.0, 0.0], 0.4)
    q_b_from_c = quaternion_from_axis_angle([0.0, 1.0, 0.0], -1.1)
    np.testing.assert_allclose(
        matrix_from_quaternion(quaternion_multiply(q_a_from_b, q_b_from_c)),
        matrix_from_quaternion(q_a_from_b) @ matrix_from_quaternion(q_b_from_c),
        atol=ATOL,
    )


def test_quaternion_rotation_is_active() -> None:
    # q_a_from_b maps a vector's coordinates in b to its coordinates in a; +90 deg about z
    # turns x into y.
    q = quaternion_from_axis_angle([0.0, 0.0, 1.0], math.pi / 2)
    np.testing.assert_allclose(rotate_vectors(q, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=ATOL)


def test_quaternions_are_written_with_nonnegative_qw() -> None:
    # SciPy may return either sign; satsight always writes the qw >= 0 one.
    R = Rotation.from_rotvec([0.0, 0.0, 1.9 * math.pi]).as_matrix()
    q = quaternion_from_matrix(R)
    assert q[0] >= 0.0
    assert quaternion_from_axis_angle([0.0, 1.0, 0.0], 1.5 * math.pi)[0] >= 0.0
    assert RigidTransform(R, np.zeros(3)).q_a_from_b[0] >= 0.0
    np.testing.assert_array_equal(canonical_quaternion(-q), q)


def test_camera_axes_are_opencv() -> None:
    cx, cy = CAMERA.cx_px, CAMERA.cy_px
    right = CAMERA.project(np.array([0.001, 0.0, 1.0]))  # +x in the camera frame
    below = CAMERA.project(np.array([0.0, 0.001, 1.0]))  # +y in the camera frame
    ahead = CAMERA.project(np.array([0.0, 0.0, 1.0]))  # +z: the boresight
    assert right[0] > cx and right[1] == pytest.approx(cy, abs=ATOL_PX)  # u grows to the right
    assert below[1] > cy and below[0] == pytest.approx(cx, abs=ATOL_PX)  # v grows downwards
    np.testing.assert_allclose(ahead, [cx, cy], atol=ATOL_PX)
    # A look-at pose points +z at the target, and the up hint appears as image up (-v).
    cam_from_body = look_at_cam_from_body([0.0, -10.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(cam_from_body.apply([0.0, 0.0, 0.0]), [0.0, 0.0, 10.0], atol=ATOL)
    above = CAMERA.project(cam_from_body.apply([0.0, 0.0, 0.01]))
    assert above[1] < cy


def test_pixel_origin_is_the_centre_of_the_top_left_pixel() -> None:
    W, H = CAMERA.width_px, CAMERA.height_px
    p, f = CAMERA.pixel_pitch_m, CAMERA.focal_length_m
    # The optical axis lands on the image centre ((W - 1) / 2, (H - 1) / 2) = (3.5, 2.5).
    np.testing.assert_allclose(CAMERA.project(np.array([0.0, 0.0, 5.0])), [3.5, 2.5], atol=0)
    assert (CAMERA.cx_px, CAMERA.cy_px) == ((W - 1) / 2, (H - 1) / 2)
    # The ray through pixel (0, 0) passes through the centre of the top-left pixel, which
    # on the (virtual, upright) image plane at z = f lies half a pixel in from the corner.
    top_left_centre_m = np.array([-(W / 2 - 0.5) * p, -(H / 2 - 0.5) * p, f])
    np.testing.assert_allclose(
        CAMERA.ray_directions_cam(np.array([0.0, 0.0])),
        top_left_centre_m / np.linalg.norm(top_left_centre_m),
        atol=ATOL,
    )


def test_continuous_image_spans_minus_half_to_size_minus_half() -> None:
    W, H = CAMERA.width_px, CAMERA.height_px
    p, f = CAMERA.pixel_pitch_m, CAMERA.focal_length_m
    # The sensor's corners, at (+-W p / 2, +-H p / 2) on the image plane z = f.
    corners_cam_m = np.array([[-W * p / 2, -H * p / 2, f], [W * p / 2, H * p / 2, f]])
    np.testing.assert_allclose(
        CAMERA.project(corners_cam_m), [[-0.5, -0.5], [W - 0.5, H - 0.5]], atol=ATOL_PX
    )


def test_depth_is_along_the_optical_axis_not_along_the_ray() -> None:
    depth_m = 100.0
    off_axis_px = np.array([[0.0, 0.0], [7.0, 5.0], [2.0, 4.5]])
    points_cam_m = CAMERA.backproject(off_axis_px, np.full(3, depth_m))
    np.testing.assert_allclose(points_cam_m[:, 2], depth_m, atol=0)
    # The distance along the ray is longer than the depth off axis.
    assert np.all(np.linalg.norm(points_cam_m, axis=-1) > depth_m)


def test_arrays_carry_components_on_the_last_axis_in_float64() -> None:
    points_cam_m = np.ones((4, 5, 3), dtype=np.float32)  # an (H, W, 3) grid of points
    uv = CAMERA.project(points_cam_m)
    assert uv.shape == (4, 5, 2)
    assert uv.dtype == np.float64
    assert rotate_vectors(np.array([1.0, 0.0, 0.0, 0.0]), points_cam_m).shape == (4, 5, 3)
    assert quaternion_from_axis_angle(np.eye(3), 0.1).shape == (3, 4)


def test_body_frame_is_the_mesh_frame_and_part_ids_start_at_one() -> None:
    # An off-centre two-part mesh keeps its vertices as given: no recentring, no axis swap.
    vertices_m = np.array([[10.0, 0.0, 0.0], [11.0, 0.0, 0.0], [10.0, 1.0, 0.0], [10.0, 0.0, 1.0]])
    mesh = TargetMesh(
        vertices_m=vertices_m,
        faces=np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3]]),
        face_part_index=np.array([0, 1, 1]),
        part_names=("bus", "panel"),
        part_materials=("mli_gold", "solar_cell"),
    )
    np.testing.assert_array_equal(mesh.vertices_m, vertices_m)
    assert mesh.vertices_m.dtype == np.float64
    # Part id = part index + 1; 0 is left for the background.
    np.testing.assert_array_equal(mesh.part_ids, [1, 2, 2])
    assert mesh.part_ids.min() >= 1


def test_label_images_on_disk(tmp_path: Path) -> None:
    # A 2 x 3 frame: background in the first column, part ids 1, 2 and 300 elsewhere.
    part_id = np.array([[0, 1, 2], [0, 300, 1]], dtype=np.uint16)
    hit = part_id > 0
    depth_m = np.where(hit, np.float32(123.25), np.float32(0.0)).astype(np.float32)
    image = RadianceImage(
        radiance_w_m2_sr=np.where(hit[..., None], np.float32(0.5), np.zeros((2, 3, 3), np.float32)),
        depth_m=depth_m,
        part_id=part_id,
        normals_cam=np.zeros((2, 3, 3), dtype=np.float32),
    )
    dn_image = DnImage(
        dn=np.array([[1000, 2000, 3000], [1000, 61000, 65535]], dtype=np.uint16),
        exposure_time_s=0.001,
        saturated_pixel_count=2,
        star_count=0,
        bias_dn=1000.0,
        full_well_dn=61000.0,
    )
    files, _, _ = write_frame_files(
        tmp_path, 0, FrameArrays(image, dn_image), OutputsConfig().file_keys(), None, True
    )
    # Raw DN: 16-bit greyscale, exactly the detector's values.
    with Image.open(tmp_path / files["dn_png16"]) as png16:
        assert png16.mode == "I;16"
        np.testing.assert_array_equal(np.asarray(png16), dn_image.dn)
    with Image.open(tmp_path / files["object_mask_png"]) as png8:
        object_mask = np.asarray(png8)
    # Object mask: 8-bit, 255 on the target, 0 elsewhere.
    assert object_mask.dtype == np.uint8
    np.testing.assert_array_equal(object_mask, np.where(hit, 255, 0))
    # Part-id mask: 16-bit, 0 background, ids above 255 survive.
    # Read back with Pillow, independently of satsight's own image readers.
    with Image.open(tmp_path / files["part_mask_png16"]) as png16:
        assert png16.mode == "I;16"
        parts = np.asarray(png16)
    assert parts.dtype == np.uint16
    np.testing.assert_array_equal(parts, part_id)
    # Depth: float32 metres along +z_cam, 0 where there is no surface.
    depth_on_disk = read_exr(tmp_path / files["depth_exr"])["Z"]
    assert depth_on_disk.dtype == np.float32
    np.testing.assert_array_equal(depth_on_disk, depth_m)
    assert np.all(depth_on_disk[~hit] == 0.0)
