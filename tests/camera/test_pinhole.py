"""The pinhole camera: the paper's presets (section 4.2, Tables 2 and 7) and the projection.

Reference values: sensor 4096 x 4112 pixels of 15 um (CCD231-84 class), f = 3 m (high
resolution) and f = 0.7 m (wide field). Table 7: a 5 m object spans about 200 px at 5 km
and about 50 px at 20 km in high-resolution mode, for a GSD of 0.025 m/px and 0.1 m/px.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from satsight.camera.pinhole import CAMERA_PRESETS, PinholeCamera
from satsight.errors import SatsightError

ATOL_PX = 1e-9  # pixel positions from float64 arithmetic
REL = 1e-12  # closed forms that the code evaluates the same way up to rounding
FIFTEEN_UM = 15e-6
WIDTH_PX, HEIGHT_PX = 4096, 4112
PROPERTY = settings(max_examples=50, deadline=None)

HIGH_RES = PinholeCamera.high_resolution()
WIDE = PinholeCamera.wide_field()
SMALL = PinholeCamera(focal_length_m=0.05, pixel_pitch_m=5e-6, width_px=64, height_px=48)


def _angle_between_rad(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two directions, accurate for small angles (atan2, not acos)."""
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


def _fov_rad(extent_px: float, pitch_m: float, focal_m: float) -> float:
    """Full field of view subtended by a sensor extent: 2 atan(n p / 2 f)."""
    return 2.0 * math.atan(extent_px * pitch_m / (2.0 * focal_m))


# --- presets -----------------------------------------------------------------------------


@pytest.mark.parametrize(("camera", "focal_m"), [(HIGH_RES, 3.0), (WIDE, 0.7)])
def test_presets_match_the_paper_camera(camera: PinholeCamera, focal_m: float) -> None:
    assert camera.width_px == WIDTH_PX
    assert camera.height_px == HEIGHT_PX
    assert camera.pixel_pitch_m == FIFTEEN_UM
    assert camera.focal_length_m == focal_m
    assert camera.focal_length_px == pytest.approx(focal_m / FIFTEEN_UM, rel=REL)
    assert camera.sensor_width_m == pytest.approx(61.44e-3, rel=REL)
    assert camera.sensor_height_m == pytest.approx(61.68e-3, rel=REL)


def test_preset_registry_builds_the_presets() -> None:
    assert set(CAMERA_PRESETS) == {"high_resolution", "wide_field"}
    assert CAMERA_PRESETS["high_resolution"]() == HIGH_RES
    assert CAMERA_PRESETS["wide_field"]() == WIDE


@pytest.mark.parametrize(
    ("range_m", "expected_px", "expected_gsd_m"),
    [(5_000.0, 200.0, 0.025), (20_000.0, 50.0, 0.1)],
)
def test_table7_object_size_and_gsd_in_high_resolution_mode(
    range_m: float, expected_px: float, expected_gsd_m: float
) -> None:
    size_m = 5.0
    assert HIGH_RES.pixels_spanned(size_m, range_m) == pytest.approx(expected_px, rel=1e-6)
    assert HIGH_RES.gsd_m(range_m) == pytest.approx(expected_gsd_m, rel=REL)
    # The same span from the projection of the object's two ends, centred on the axis.
    ends = HIGH_RES.project(np.array([[-size_m / 2, 0.0, range_m], [size_m / 2, 0.0, range_m]]))
    assert ends[1, 0] - ends[0, 0] == pytest.approx(expected_px, rel=1e-9)
    # GSD times pixels spanned gives back the object size.
    assert expected_gsd_m * expected_px == pytest.approx(size_m, rel=1e-12)


def test_wide_field_mode_is_3_m_over_0_7_m_coarser() -> None:
    ratio = 3.0 / 0.7
    assert WIDE.gsd_m(5_000.0) == pytest.approx(0.025 * ratio, rel=REL)  # ~0.107 m/px
    assert WIDE.pixels_spanned(5.0, 5_000.0) == pytest.approx(200.0 / ratio, rel=1e-9)  # ~46.7


def test_gsd_is_range_times_ifov_and_broadcasts() -> None:
    assert HIGH_RES.ifov_rad == pytest.approx(5e-6, rel=REL)  # 15 um / 3 m
    ranges_m = np.array([1_000.0, 5_000.0, 20_000.0])
    np.testing.assert_allclose(HIGH_RES.gsd_m(ranges_m), ranges_m * 5e-6, rtol=REL)


# --- field of view -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("camera", "fov_x_deg", "fov_y_deg", "fov_diagonal_deg"),
    [(HIGH_RES, 1.1734, 1.1780, 1.6626), (WIDE, 5.0257, 5.0453, 7.1167)],
)
def test_field_of_view_from_the_physics(
    camera: PinholeCamera, fov_x_deg: float, fov_y_deg: float, fov_diagonal_deg: float
) -> None:
    p, f = camera.pixel_pitch_m, camera.focal_length_m
    assert camera.fov_x_rad == pytest.approx(_fov_rad(WIDTH_PX, p, f), rel=REL)
    assert camera.fov_y_rad == pytest.approx(_fov_rad(HEIGHT_PX, p, f), rel=REL)
    diagonal_px = math.hypot(WIDTH_PX, HEIGHT_PX)
    assert camera.fov_diagonal_rad == pytest.approx(_fov_rad(diagonal_px, p, f), rel=REL)
    # Rounded values (to 1e-4 deg) as quoted in docs: 1.173 deg high resolution, 5.03 deg wide.
    assert math.degrees(camera.fov_x_rad) == pytest.approx(fov_x_deg, abs=1e-4)
    assert math.degrees(camera.fov_y_rad) == pytest.approx(fov_y_deg, abs=1e-4)
    assert math.degrees(camera.fov_diagonal_rad) == pytest.approx(fov_diagonal_deg, abs=1e-4)
    # 4112 rows > 4096 columns, and the diagonal is the widest.
    assert camera.fov_x_rad < camera.fov_y_rad < camera.fov_diagonal_rad


@pytest.mark.parametrize("camera", [HIGH_RES, WIDE, SMALL])
def test_field_of_view_is_the_angle_between_the_sensor_edges(camera: PinholeCamera) -> None:
    # The sensor's outer edges are at u = -0.5 and u = W - 0.5 (pixel centres are integers).
    W, H = camera.width_px, camera.height_px
    edges = camera.ray_directions_cam(np.array([[-0.5, camera.cy_px], [W - 0.5, camera.cy_px]]))
    assert _angle_between_rad(edges[0], edges[1]) == pytest.approx(camera.fov_x_rad, rel=1e-9)
    edges = camera.ray_directions_cam(np.array([[camera.cx_px, -0.5], [camera.cx_px, H - 0.5]]))
    assert _angle_between_rad(edges[0], edges[1]) == pytest.approx(camera.fov_y_rad, rel=1e-9)
    corners = camera.ray_directions_cam(np.array([[-0.5, -0.5], [W - 0.5, H - 0.5]]))
    assert _angle_between_rad(*corners) == pytest.approx(camera.fov_diagonal_rad, rel=1e-9)


# --- intrinsics --------------------------------------------------------------------------


@pytest.mark.parametrize("camera", [HIGH_RES, WIDE, SMALL])
def test_principal_point_is_the_sensor_centre(camera: PinholeCamera) -> None:
    assert camera.cx_px == (camera.width_px - 1) / 2
    assert camera.cy_px == (camera.height_px - 1) / 2
    np.testing.assert_allclose(
        camera.project(np.array([0.0, 0.0, 7.0])), [camera.cx_px, camera.cy_px], atol=0
    )


def test_intrinsic_matrix_layout() -> None:
    f = 0.05 / 5e-6
    np.testing.assert_allclose(
        SMALL.K, [[f, 0.0, 31.5], [0.0, f, 23.5], [0.0, 0.0, 1.0]], rtol=REL, atol=0
    )


@pytest.mark.parametrize(
    "camera", [HIGH_RES, SMALL, PinholeCamera(0.1, 10e-6, 32, 16, cx_px=10.25, cy_px=3.0)]
)
def test_K_agrees_with_project(camera: PinholeCamera) -> None:
    rng = np.random.default_rng(6)
    points_cam_m = rng.uniform([-5.0, -5.0, 10.0], [5.0, 5.0, 1_000.0], size=(100, 3))
    homogeneous = points_cam_m @ camera.K.T
    np.testing.assert_allclose(
        camera.project(points_cam_m), homogeneous[:, :2] / homogeneous[:, 2:], atol=ATOL_PX
    )


def test_ifov_is_the_angle_of_one_central_pixel() -> None:
    # Rays through the two pixels either side of the centre are atan(1.5 p/f) - atan(0.5 p/f)
    # apart, which is p / f to a relative 1e-9 for p / f ~ 2e-5.
    camera = PinholeCamera(0.7, 15e-6, 4, 4)  # even size: the centre lies between pixels
    rays = camera.ray_directions_cam(np.array([[1.0, 1.5], [2.0, 1.5]]))
    assert _angle_between_rad(*rays) == pytest.approx(camera.ifov_rad, rel=1e-8)


# --- projection ----------------------------------------------------------------------------


@PROPERTY
@given(
    st.floats(min_value=-0.5, max_value=WIDTH_PX - 0.5),
    st.floats(min_value=-0.5, max_value=HEIGHT_PX - 0.5),
    st.floats(min_value=1.0, max_value=1e5),
)
def test_backproject_then_project_round_trips(u_px: float, v_px: float, depth_m: float) -> None:
    for camera in (HIGH_RES, WIDE):
        point_cam_m = camera.backproject(np.array([u_px, v_px]), depth_m)
        assert point_cam_m[2] == depth_m
        np.testing.assert_allclose(camera.project(point_cam_m), [u_px, v_px], atol=ATOL_PX)


@PROPERTY
@given(
    st.floats(min_value=-1e3, max_value=1e3),
    st.floats(min_value=-1e3, max_value=1e3),
    st.floats(min_value=1e-2, max_value=1e6),
)
def test_project_then_backproject_round_trips(x_m: float, y_m: float, z_m: float) -> None:
    point_cam_m = np.array([x_m, y_m, z_m])
    uv = SMALL.project(point_cam_m)
    np.testing.assert_allclose(SMALL.backproject(uv, z_m), point_cam_m, rtol=1e-12, atol=1e-9)
    # The unit ray through that pixel points at the point.
    ray = SMALL.ray_directions_cam(uv)
    np.testing.assert_allclose(ray, point_cam_m / np.linalg.norm(point_cam_m), atol=1e-12)


def test_projection_keeps_batch_shapes() -> None:
    points_cam_m = np.random.default_rng(7).uniform(1.0, 2.0, size=(5, 6, 3))
    uv = SMALL.project(points_cam_m)
    assert uv.shape == (5, 6, 2)
    np.testing.assert_allclose(uv[4, 2], SMALL.project(points_cam_m[4, 2]), atol=0)
    depth_m = points_cam_m[..., 2]
    np.testing.assert_allclose(SMALL.backproject(uv, depth_m), points_cam_m, rtol=1e-12)
    rays = SMALL.ray_directions_cam(uv)
    assert rays.shape == (5, 6, 3)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0, atol=1e-15)


def test_points_at_or_behind_the_camera_give_nan() -> None:
    points_cam_m = np.array(
        [[0.0, 0.0, 10.0], [1.0, 1.0, -10.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -0.0]]
    )
    uv = HIGH_RES.project(points_cam_m)
    assert np.all(np.isfinite(uv[0]))
    assert np.all(np.isnan(uv[1:]))
    # A single point behind the camera.
    assert np.all(np.isnan(HIGH_RES.project(np.array([0.1, 0.2, -3.0]))))


def test_projection_is_perspective_not_mirrored() -> None:
    # Twice as far away: half the offset from the principal point, same side.
    near = SMALL.project(np.array([1.0, -0.5, 10.0]))
    far = SMALL.project(np.array([1.0, -0.5, 20.0]))
    centre = np.array([SMALL.cx_px, SMALL.cy_px])
    np.testing.assert_allclose(far - centre, 0.5 * (near - centre), atol=ATOL_PX)


# --- construction --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        {"focal_length_m": 0.0},
        {"focal_length_m": -3.0},
        {"focal_length_m": math.nan},
        {"focal_length_m": math.inf},
        {"pixel_pitch_m": 0.0},
        {"pixel_pitch_m": -15e-6},
        {"pixel_pitch_m": math.nan},
        {"width_px": 0},
        {"height_px": -4},
        {"width_px": 10.5},
        {"height_px": math.nan},
        {"width_px": "wide"},
    ],
)
def test_invalid_parameters_raise(kwargs: dict) -> None:
    args = {"focal_length_m": 3.0, "pixel_pitch_m": 15e-6, "width_px": 16, "height_px": 8}
    args.update(kwargs)
    (name,) = kwargs
    message = {
        "focal_length_m": "focal length must be positive",
        "pixel_pitch_m": "pixel pitch must be positive",
    }.get(name, "image size must be whole numbers of pixels, at least 1 x 1")
    with pytest.raises(SatsightError, match=message):
        PinholeCamera(**args)


def test_whole_float_and_numpy_sizes_are_accepted_as_int() -> None:
    camera = PinholeCamera(3.0, 15e-6, np.int64(16), 8.0)
    assert (camera.width_px, camera.height_px) == (16, 8)
    assert isinstance(camera.width_px, int) and isinstance(camera.height_px, int)


@pytest.mark.parametrize(
    ("method", "bad"), [("project", np.ones((4, 2))), ("ray_directions_cam", np.ones((4, 3)))]
)
def test_bad_array_shapes_raise(method: str, bad: np.ndarray) -> None:
    with pytest.raises(SatsightError, match="last axis"):
        getattr(SMALL, method)(bad)
    with pytest.raises(SatsightError, match="last axis"):
        SMALL.backproject(np.ones((4, 3)), np.ones(4))


def test_with_size_recentres_the_principal_point() -> None:
    shifted = PinholeCamera(3.0, 15e-6, 4096, 4112, cx_px=100.0, cy_px=200.0)
    small = shifted.with_size(512, 256)
    assert (small.width_px, small.height_px) == (512, 256)
    assert (small.cx_px, small.cy_px) == (255.5, 127.5)
    assert small.focal_length_m == shifted.focal_length_m
    assert small.pixel_pitch_m == shifted.pixel_pitch_m
    assert small.ifov_rad == HIGH_RES.ifov_rad  # same optics, same GSD
    # Fewer pixels of the same size: the field of view shrinks accordingly.
    assert small.fov_x_rad == pytest.approx(_fov_rad(512, 15e-6, 3.0), rel=REL)
    with pytest.raises(SatsightError, match="at least 1 x 1; got 0 x 10"):
        HIGH_RES.with_size(0, 10)
