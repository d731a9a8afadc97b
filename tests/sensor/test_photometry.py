"""Photometric labels: pixel solid angles, the target's footprint, and the irradiance and
V-equivalent magnitude of a rendered Lambertian plate against their closed forms.

Pixelisation tolerance of a rendered plate: with s x s sub-pixel samples on a regular grid
(one path each, at the cell centres), a straight edge crossing a pixel is counted column by
column (or row by row) with an error of at most half a cell per column, so the pixel's
covered fraction is off by at most 1 / (2 s). An edge from (u0, v0) to (u1, v1) crosses at
most |u1 - u0| + |v1 - v0| + 1 pixels; the plate's summed radiance is therefore within
sum over edges (|du| + |dv| + 1) / (2 s) pixel areas of L times its projected area, and
the relative tolerance is that over the projected area in pixels.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from builders import plate_parts
from satsight.camera.pinhole import PinholeCamera
from satsight.constants import AU_M
from satsight.errors import SatsightError
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.lighting.solar_spectrum import load_e490
from satsight.render.buffers import RadianceImage
from satsight.render.renderer import Renderer
from satsight.render.settings import RenderSettings
from satsight.scene.materials import Material
from satsight.scene.mesh import merge_parts
from satsight.scene.procedural import generate_satellite
from satsight.sensor.photometry import (
    SUN_V_MAGNITUDE_AT_1_AU,
    frame_photometry,
    pixel_solid_angles_sr,
    sun_v_magnitude,
    target_footprint,
    target_irradiance_w_m2,
    v_magnitude_equivalent,
)
from satsight.sensor.star_photometry import V_EFFECTIVE_WAVELENGTH_NM, V_ZERO_POINT_W_M2_NM

E_SUN_W_M2 = 671.5
RHO = (0.6, 0.4, 0.8)
# Any weights summing to 1 combine the channels (the sensor's come from the solar spectrum).
WEIGHTS = np.array([0.25, 0.35, 0.40])
RHO_BAND = float(np.dot(WEIGHTS, RHO))
PLATE_SIDE_M = 2.0
THETA_I = math.radians(35.0)  # Sun from the plate's normal
THETA_O = math.radians(20.0)  # camera from the plate's normal
SUPERSAMPLING = 8  # the renderer's largest: 8 x 8 sub-pixel samples


# --- pixel solid angles --------------------------------------------------------------------
def _exact_solid_angles_sr(camera: PinholeCamera, width: int, height: int) -> np.ndarray:
    """The exact solid angles of a camera's pixels: F(x_b, y_b) - F(x_a, y_b) - F(x_b, y_a)
    + F(x_a, y_a) over each footprint [x_a, x_b] x [y_a, y_b] on the focal plane, with
    F(x, y) = atan(x y / (f sqrt(f^2 + x^2 + y^2))) the integral of
    f dx dy / (f^2 + x^2 + y^2)^(3/2) over [0, x] x [0, y] (odd in x and in y)."""
    f, p = camera.focal_length_m, camera.pixel_pitch_m
    x = (np.arange(width + 1) - 0.5 - camera.cx_px) * p
    y = (np.arange(height + 1) - 0.5 - camera.cy_px) * p
    X, Y = x[None, :], y[:, None]
    corner = np.arctan(X * Y / (f * np.sqrt(f * f + X * X + Y * Y)))
    return corner[1:, 1:] - corner[:-1, 1:] - corner[1:, :-1] + corner[:-1, :-1]


@pytest.mark.parametrize(("focal_length_m", "rtol"), [(3.0, 5e-9), (0.7, 5e-9), (0.05, 3e-8)])
def test_pixel_solid_angles_are_the_exact_ones(focal_length_m, rtol) -> None:
    """(p / f)^2 cos^3(theta) at the pixel centres against the exact footprint solid angles:
    within (p / f)^2 / 4 relative (2.2e-8 at f = 5 cm), or float64's resolution of the exact
    formula (~3e-9) at the paper's focal lengths; and they sum to the whole sensor's solid
    angle, 4 atan(a b / (f sqrt(f^2 + a^2 + b^2))) with half-sides a, b."""
    camera = PinholeCamera(focal_length_m, 15e-6, 4096, 4112)
    omega = pixel_solid_angles_sr(camera, (0, 0, 4096, 4112))
    np.testing.assert_allclose(omega, _exact_solid_angles_sr(camera, 4096, 4112), rtol=rtol)
    a, b, f = camera.sensor_width_m / 2, camera.sensor_height_m / 2, focal_length_m
    whole = 4.0 * math.atan(a * b / (f * math.sqrt(f * f + a * a + b * b)))
    assert omega.sum() == pytest.approx(whole, rel=rtol)
    corner = pixel_solid_angles_sr(camera, (4090, 4100, 4096, 4112))
    np.testing.assert_array_equal(corner, omega[4100:4112, 4090:4096])


def test_solid_angles_of_an_off_centre_principal_point() -> None:
    camera = PinholeCamera(3.0, 15e-6, 64, 48, cx_px=-100.5, cy_px=10.0)
    omega = pixel_solid_angles_sr(camera, (0, 0, 64, 48))
    np.testing.assert_allclose(omega, _exact_solid_angles_sr(camera, 64, 48), rtol=1e-8)
    assert omega[0, 0] < omega[10, 0]  # the pixel at (0, 10) lies on the axis's row
    with pytest.raises(SatsightError, match="x1 >= x0"):
        pixel_solid_angles_sr(camera, (5, 0, 4, 3))


# --- footprint -----------------------------------------------------------------------------
def test_footprint_without_a_body_drawn_is_the_projected_box() -> None:
    """No Earth or Moon in the frame: every pixel whose footprint meets the target's
    projected box is summed, mask or not (the light of parts thinner than a pixel)."""
    mask = np.zeros((20, 30), dtype=bool)
    corners = [[11.8, 6.6], [13.4, 6.6], [11.8, 7.3], [13.4, 7.3]]
    box, region = target_footprint(mask, corners)
    assert box == (12, 7, 14, 8) and region.all()
    mask[7, 12] = True
    again, region_again = target_footprint(mask, corners)
    assert again == box and np.array_equal(region_again, region)
    # The box's pixels: the pixel holding u is floor(u + 0.5).
    assert target_footprint(mask, [[9.5, 4.49], [14.49, 9.5]])[0] == (10, 4, 15, 11)
    assert target_footprint(mask, [[-9.0, -9.0], [-5.0, -5.0]]) is None  # off the image
    # A corner at or behind the camera plane: the target may be anywhere in the frame.
    assert target_footprint(mask, [[1.0, 1.0], None])[0] == (0, 0, 30, 20)
    assert target_footprint(mask)[0] == (0, 0, 30, 20)


def test_footprint_with_a_body_drawn_keeps_away_from_it_but_around_the_mask() -> None:
    """The Earth's disc in the frame: the box's pixels within one pixel of a centre that
    sees it are left out, unless within one pixel of the object mask."""
    mask = np.zeros((20, 30), dtype=bool)
    mask[5:8, 10:14] = True
    earth = np.zeros((20, 30), dtype=np.uint8)
    earth[:, 20:] = 1  # the Earth fills columns 20 and beyond
    corners = [[8.6, 3.6], [21.4, 3.6], [8.6, 9.4], [21.4, 9.4]]
    box, region = target_footprint(mask, corners, earth)
    assert box == (9, 4, 22, 10)
    expected = np.ones((6, 13), dtype=bool)
    expected[:, 19 - 9 :] = False  # columns 19-21: within one pixel of the Earth
    np.testing.assert_array_equal(region, expected)
    # Against the Earth: only the mask and its one-pixel ring.
    earth[:] = 1
    earth[mask] = 0
    box, region = target_footprint(mask, corners, earth)
    ring = np.zeros((20, 30), dtype=bool)
    ring[4:9, 9:15] = True
    np.testing.assert_array_equal(region, ring[4:10, 9:22])
    # No pixel centre on the target, and the Earth behind it: nothing is summed.
    assert target_footprint(np.zeros_like(mask), corners, np.ones_like(earth)) is None
    # A body elsewhere in the frame changes nothing near the target.
    earth[:] = 0
    earth[18:, 28:] = 2
    box, region = target_footprint(mask, corners, earth)
    assert box == (9, 4, 22, 10) and region.all()


# --- magnitudes ----------------------------------------------------------------------------
def test_sun_v_magnitude_follows_the_inverse_square_law() -> None:
    assert sun_v_magnitude(AU_M) == SUN_V_MAGNITUDE_AT_1_AU == -26.76
    assert sun_v_magnitude(10 * AU_M) == pytest.approx(-21.76, abs=1e-12)
    # A magnitude measures the irradiance at the camera alone: the same E_target is the same
    # magnitude whatever the Sun's distance (E_sun d^2 is fixed); a target twice as far from
    # the Sun sends a quarter of the light, 2.5 log10(4) = 1.505 mag fainter.
    at_1_au = v_magnitude_equivalent(1e-12 / 4, 1360.0, AU_M)
    at_2_au = v_magnitude_equivalent(1e-12 / 4, 1360.0 / 4, 2 * AU_M)
    assert at_1_au == pytest.approx(at_2_au, abs=1e-12)
    brighter = v_magnitude_equivalent(1e-12, 1360.0, AU_M)
    assert at_2_au - brighter == pytest.approx(2.5 * math.log10(4.0), abs=1e-12)
    assert v_magnitude_equivalent(0.0, 1360.0, AU_M) is None
    with pytest.raises(SatsightError, match="irradiance must be positive"):
        v_magnitude_equivalent(1.0, 0.0, AU_M)


def test_the_suns_v_magnitude_agrees_with_the_star_zero_point_and_the_solar_spectrum() -> None:
    """The stars in the images are scaled to the V zero point of Bessell et al. 1998 (3.631e-11
    W m^-2 nm^-1 at 545 nm); the shipped E-490 Sun at 545 nm, on that scale, is V = -26.79
    (averaged over 500-590 nm: -26.77), within 0.05 mag of Willmer's -26.76: a target's
    V-equivalent magnitude and a solar-type star's V mean the same photons."""
    wavelength_m, irradiance_w_m2_m = load_e490()
    for lo, hi in ((545.0, 545.0), (500.0, 590.0)):
        lam = np.linspace(lo, hi, 901) * 1e-9
        f_nm = float(np.mean(np.interp(lam, wavelength_m, irradiance_w_m2_m))) * 1e-9
        v_sun = -2.5 * math.log10(f_nm / V_ZERO_POINT_W_M2_NM)
        assert v_sun == pytest.approx(SUN_V_MAGNITUDE_AT_1_AU, abs=0.05), (lo, hi)
    assert V_EFFECTIVE_WAVELENGTH_NM == 545.0


# --- a rendered Lambertian plate -----------------------------------------------------------
@pytest.fixture(scope="module")
def plate_renderer(llvm_variant):
    v, f = plate_parts(size_m=PLATE_SIDE_M)
    material = Material("plate_lambert", RHO, metallic=0.0, roughness=1.0, ior=1.0)
    mesh = merge_parts([("plate", material.name, v, f)], {material.name: material}, "plate")

    def render(camera: PinholeCamera, distance_m: float, supersampling: int):
        settings = RenderSettings(environment="off", bounces=0, supersampling=supersampling)
        position = distance_m * np.array([math.sin(THETA_O), 0.0, math.cos(THETA_O)])
        # Rolled 30 deg about the line of sight: no edge runs along a pixel row or column.
        up = (math.sin(math.radians(30.0)), math.cos(math.radians(30.0)), 0.0)
        pose = look_at_cam_from_body(position, np.zeros(3), up_hint_body=up)
        sun = np.array([-math.sin(THETA_I), 0.0, math.cos(THETA_I)])
        light = LightField.sun_only(sun, E_SUN_W_M2)
        image = Renderer(mesh, settings, llvm_variant).render(camera, pose, light, seed=1)
        corners_px = camera.project(pose.apply(v)).tolist()
        return image, corners_px

    return render


def _plate_closed_form_w_m2(distance_m: float) -> float:
    """E = rho E_sun A cos(theta_i) cos(theta_o) / (pi d^2), in band."""
    area = PLATE_SIDE_M**2
    return (
        RHO_BAND
        * E_SUN_W_M2
        * area
        * math.cos(THETA_I)
        * math.cos(THETA_O)
        / (math.pi * distance_m**2)
    )


def _pixelisation_rtol(corners_px: list, supersampling: int) -> float:
    """Worst-case relative error of the rendered plate's summed radiance (module docstring)."""
    uv = np.asarray(corners_px)
    edges = uv[[1, 2, 3, 0]] - uv  # corners in order around the plate
    crossed = np.sum(np.abs(edges).sum(axis=1) + 1.0)
    x, y = uv[:, 0], uv[:, 1]
    area_px = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return crossed / (2.0 * supersampling) / area_px


@pytest.mark.parametrize(("distance_m", "size_px"), [(5_000.0, 112), (50_000.0, 32)])
def test_plate_irradiance_and_magnitude_match_the_closed_form(
    plate_renderer, distance_m, size_px
) -> None:
    """A 2 m Lambertian plate, Sun 35 deg and camera 20 deg from its normal, 80 px (5 km) and
    8 px (50 km) across with f = 3 m, 8 x 8 sub-pixel samples: E within the pixelisation
    bound of the closed form (0.44 % and 4.8 %; measured 1.0e-5 and 2.6e-4), and the
    magnitude likewise."""
    camera = PinholeCamera(3.0, 15e-6, size_px, size_px)
    image, corners_px = plate_renderer(camera, distance_m, SUPERSAMPLING)
    labels = frame_photometry(image, camera, WEIGHTS, corners_px, E_SUN_W_M2, AU_M)
    expected = _plate_closed_form_w_m2(distance_m)
    rtol = _pixelisation_rtol(corners_px, SUPERSAMPLING)
    assert rtol < 0.06
    assert labels["target_irradiance_w_m2"] == pytest.approx(expected, rel=rtol)
    magnitude = SUN_V_MAGNITUDE_AT_1_AU - 2.5 * math.log10(expected / E_SUN_W_M2)
    assert labels["target_v_magnitude_equivalent"] == pytest.approx(
        magnitude, abs=2.5 * math.log10(1.0 + rtol)
    )
    # Nothing outside the footprint holds light: the sum is all the rendered radiance, and
    # the pixels of the one-pixel ring around the mask hold some of it.
    band = image.radiance_w_m2_sr @ WEIGHTS
    omega = pixel_solid_angles_sr(camera, (0, 0, size_px, size_px))
    everywhere = float(np.sum(band * omega))
    assert labels["target_irradiance_w_m2"] == pytest.approx(everywhere, rel=1e-6)
    centres_only = float(np.sum(np.where(image.object_mask, band, 0.0) * omega))
    assert centres_only != pytest.approx(everywhere, rel=1e-4)


def test_ten_times_the_distance_is_five_magnitudes_fainter(plate_renderer) -> None:
    """The same plate at 5 km and at 50 km, 80 px across in both (f = 3 m, then 30 m: the
    irradiance at the camera does not depend on the camera): 5 magnitudes apart, within the
    two renders' pixelisation bounds (0.005 mag each)."""
    magnitudes, tolerance = [], 0.0
    for distance_m, focal_length_m in ((5_000.0, 3.0), (50_000.0, 30.0)):
        camera = PinholeCamera(focal_length_m, 15e-6, 112, 112)
        image, corners_px = plate_renderer(camera, distance_m, SUPERSAMPLING)
        labels = frame_photometry(image, camera, WEIGHTS, corners_px, E_SUN_W_M2, AU_M)
        magnitudes.append(labels["target_v_magnitude_equivalent"])
        tolerance += 2.5 * math.log10(1.0 + _pixelisation_rtol(corners_px, SUPERSAMPLING))
    assert tolerance < 0.011
    assert magnitudes[1] - magnitudes[0] == pytest.approx(5.0, abs=tolerance)


def test_a_satellite_smaller_than_its_pixels_keeps_all_its_light(llvm_variant) -> None:
    """A procedural satellite at 300 km (f = 3 m, 15 um pixels: 7 m across, 5 px), seen
    along its wings, which are thinner than a pixel: no pixel centre meets it (empty object
    mask), yet the supersampled render holds its light, and the label holds all of it."""
    mesh = generate_satellite("two_wings", 3)
    settings = RenderSettings(environment="off", bounces=1, supersampling=4)
    camera = PinholeCamera(3.0, 15e-6, 32, 32)
    direction = np.array([0.0, 1.0, 0.2]) / np.linalg.norm([0.0, 1.0, 0.2])
    pose = look_at_cam_from_body(
        mesh.center_m + 300e3 * direction, mesh.center_m, up_hint_body=(0.0, 0.0, 1.0)
    )
    sun = np.array([0.2, 0.9, 0.4]) / np.linalg.norm([0.2, 0.9, 0.4])
    image = Renderer(mesh, settings, llvm_variant).render(
        camera, pose, LightField.sun_only(sun, E_SUN_W_M2), seed=1
    )
    corners_px = camera.project(pose.apply(mesh.box_keypoints_body_m[:8])).tolist()
    labels = frame_photometry(image, camera, WEIGHTS, corners_px, E_SUN_W_M2, AU_M)
    omega = pixel_solid_angles_sr(camera, (0, 0, 32, 32))
    band = image.radiance_w_m2_sr @ WEIGHTS
    everywhere = float(np.sum(band * omega))
    assert not image.object_mask.any() and everywhere > 0
    assert labels["target_irradiance_w_m2"] == pytest.approx(everywhere, rel=1e-6)
    # In front of the Earth's disc only the mask's ring would count: here, nothing.
    earth = np.ones(image.shape, dtype=np.uint8)
    assert target_footprint(image.object_mask, corners_px, earth) is None


def test_an_unlit_frame_has_zero_irradiance_and_no_magnitude() -> None:
    camera = PinholeCamera(3.0, 15e-6, 16, 12)
    part_id = np.zeros((12, 16), dtype=np.uint16)
    part_id[4:7, 5:9] = 1
    image = RadianceImage(
        np.zeros((12, 16, 3), np.float32),
        np.where(part_id > 0, 100.0, 0.0).astype(np.float32),
        part_id,
        np.zeros((12, 16, 3), np.float32),
    )
    labels = frame_photometry(image, camera, WEIGHTS, None, E_SUN_W_M2, AU_M)
    assert labels == {"target_irradiance_w_m2": 0.0, "target_v_magnitude_equivalent": None}
    with pytest.raises(SatsightError, match="does not match the camera"):
        target_irradiance_w_m2(np.zeros((12, 15, 3)), WEIGHTS, camera, None)


def test_a_body_behind_the_target_reaches_the_label_only_through_the_ring() -> None:
    """The Earth's disc behind the target: its light counts in the mask's one-pixel ring
    (the pixels that also hold the target's edge light), nowhere else."""
    camera = PinholeCamera(3.0, 15e-6, 40, 30)
    part_id = np.zeros((30, 40), dtype=np.uint16)
    part_id[10:14, 20:25] = 1
    radiance = np.full((30, 40, 3), 7.0, np.float32)  # the Earth everywhere
    radiance[10:14, 20:25] = 50.0
    earth = np.where(part_id > 0, 0, 1).astype(np.uint8)
    image = RadianceImage(
        radiance, part_id.astype(np.float32), part_id, radiance * 0, background_id=earth
    )
    corners = [[18.7, 8.8], [25.6, 8.8], [18.7, 14.2], [25.6, 14.2]]
    labels = frame_photometry(image, camera, WEIGHTS, corners, E_SUN_W_M2, AU_M)
    omega = pixel_solid_angles_sr(camera, (0, 0, 40, 30))
    ring = np.zeros((30, 40), dtype=bool)
    ring[9:15, 19:26] = True
    expected = float(np.sum(np.where(ring, radiance @ WEIGHTS, 0.0) * omega))
    assert labels["target_irradiance_w_m2"] == pytest.approx(expected, rel=1e-6)
    # Against black space the whole projected box is the target's (its corner pixels,
    # (19, 9) ... (26, 14), included).
    radiance[~ring] = 0.0
    space = RadianceImage(radiance, part_id.astype(np.float32), part_id, radiance * 0)
    labels = frame_photometry(space, camera, WEIGHTS, corners, E_SUN_W_M2, AU_M)
    assert labels["target_irradiance_w_m2"] == pytest.approx(expected, rel=1e-6)
