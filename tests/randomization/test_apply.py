"""A frame's draws applied: materials, sensor chain, the Sun's direction and the pose
rotations, against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.camera.pinhole import PinholeCamera
from satsight.randomization.apply import (
    MIN_ROUGHNESS,
    attitude_jitter_transform,
    jittered_direction,
    perpendicular_basis,
    roll_transform,
    swapped_name,
    varied_material,
    varied_sensor,
)
from satsight.randomization.draws import MaterialDraw, PoseDraw, SensorDraw, SunDraw
from satsight.scene.materials import resolve_material
from satsight.sensor.chain import SensorChain
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.exposure_rule import ExposureRule
from satsight.sensor.optics import Optics
from satsight.vectors import angle_between_rad


def _chain(exposure: ExposureRule) -> SensorChain:
    camera = PinholeCamera.high_resolution().with_size(64, 48)
    return SensorChain(
        camera=camera,
        optics=Optics.for_preset("high_resolution"),
        detector=DetectorParameters(pixel_pitch_m=camera.pixel_pitch_m),
        band_nm=(450.0, 900.0),
        exposure=exposure,
    )


def test_a_varied_material_scales_and_clips() -> None:
    gold = resolve_material("mli_gold")
    varied = varied_material(gold, MaterialDraw(1.2, 0.9, 0.05))
    assert varied.roughness == pytest.approx(gold.roughness * 1.2, rel=1e-15)
    np.testing.assert_allclose(varied.base_color_rgb, np.array(gold.base_color_rgb) * 0.9)
    assert varied.ior == pytest.approx(gold.ior + 0.05)
    assert varied.metallic == gold.metallic and varied.name == gold.name
    bright = varied_material(gold, MaterialDraw(1e-3, 50.0, -5.0))
    assert bright.roughness == MIN_ROUGHNESS
    assert max(bright.base_color_rgb) == 1.0 and bright.ior == 1.05


def test_a_varied_sensor_takes_the_drawn_detector_and_optics() -> None:
    chain = _chain(ExposureRule(mode="fixed", time_s=0.01))
    draw = SensorDraw(1.5, 2.0, 1.1, 30.0, 20e-6, 1e-6)
    varied = varied_sensor(chain, draw)
    assert varied.detector.read_noise_e == pytest.approx(2.0 * chain.detector.read_noise_e)
    assert varied.detector.conversion_gain_e_per_dn == pytest.approx(
        1.1 * chain.detector.conversion_gain_e_per_dn
    )
    assert varied.detector.prnu_fraction == 0.2  # 30 x 1 % capped at the detector's 20 %
    assert varied.optics.defocus_blur_diameter_m == 20e-6
    assert varied.optics.jitter_rms_rad == 1e-6
    # A wider blur, a wider kernel; the kernel still sums to 1.
    assert varied.psf.shape[0] > chain.psf.shape[0]
    assert float(varied.psf.sum()) == pytest.approx(1.0, abs=1e-5)
    # The fixed exposure scaled by the factor.
    empty = np.zeros((48, 64), np.float32)
    assert varied.exposure_time_s(empty, empty > 0) == pytest.approx(0.015, rel=1e-15)


def test_the_exposure_factor_scales_the_auto_exposure_within_its_bounds() -> None:
    rule = ExposureRule(mode="auto", fill_fraction=0.5, max_time_s=1.0)
    chain = _chain(rule)
    irradiance = np.full((48, 64), 1e-6, np.float32)
    mask = np.zeros((48, 64), bool)
    mask[10:20, 10:20] = True
    base = chain.exposure_time_s(irradiance, mask)
    doubled = varied_sensor(chain, SensorDraw(2.0, 1.0, 1.0, 1.0, 0.0, 0.0))
    assert doubled.exposure_time_s(irradiance, mask) == pytest.approx(min(2 * base, 1.0))


def test_the_sun_turns_by_the_drawn_angle_towards_its_azimuth() -> None:
    d = np.array([0.3, -0.5, 0.8])
    d /= np.linalg.norm(d)
    e1, e2 = perpendicular_basis(d)
    np.testing.assert_allclose(np.cross(e1, e2), d, atol=1e-15)
    for phi in (0.0, 1.0, 4.0):
        turned = jittered_direction(d, SunDraw(1.0, 0.1, phi))
        assert float(angle_between_rad(turned, d)) == pytest.approx(0.1, rel=1e-12)
        # Its offset lies along cos(phi) e1 + sin(phi) e2.
        offset = turned - d * float(turned @ d)
        assert math.atan2(offset @ e2, offset @ e1) == pytest.approx(
            math.atan2(math.sin(phi), math.cos(phi)), abs=1e-12
        )
    np.testing.assert_array_equal(jittered_direction(d, SunDraw(1.0, 0.0, 2.0)), d)


def test_a_rolled_camera_sees_the_image_turned_about_its_centre() -> None:
    # A camera turned by +30 deg about its boresight sees a point on its old +x axis at
    # -30 deg: x' = cos(30) x, y' = -sin(30) x; the boresight stays put.
    rolled = roll_transform(PoseDraw(math.radians(30.0), 0.0, (0.0, 0.0, 1.0)))
    np.testing.assert_allclose(
        rolled.apply([1.0, 0.0, 5.0]), [math.cos(math.pi / 6), -0.5, 5.0], atol=1e-15
    )
    np.testing.assert_allclose(rolled.apply([0.0, 0.0, 5.0]), [0.0, 0.0, 5.0], atol=1e-15)


def test_attitude_jitter_turns_the_target_about_its_box_centre() -> None:
    center = np.array([0.2, -0.1, 0.4])
    draw = PoseDraw(0.0, 0.05, (0.0, 0.6, 0.8))
    body_from_jittered = attitude_jitter_transform(draw, center)
    np.testing.assert_allclose(body_from_jittered.apply(center), center, atol=1e-15)
    # A point on the axis through the centre stays; one off it turns by the angle.
    on_axis = center + np.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose(body_from_jittered.apply(on_axis), on_axis, atol=1e-15)
    off = np.array([1.0, 0.0, 0.0])
    moved = body_from_jittered.apply(center + off) - center
    assert float(angle_between_rad(moved, off)) == pytest.approx(0.05, rel=1e-12)


def test_a_swap_picks_each_candidate_for_its_share_of_the_choice() -> None:
    candidates = ("a", "b", "c")
    picks = [
        swapped_name(candidates, MaterialDraw(1.0, 1.0, 0.0, True, u))
        for u in (0.0, 0.33, 0.34, 0.66, 0.67, 0.999)
    ]
    assert picks == ["a", "a", "b", "b", "c", "c"]
    assert swapped_name(candidates, MaterialDraw(1.0, 1.0, 0.0, False, 0.5)) is None
    assert swapped_name((), MaterialDraw(1.0, 1.0, 0.0, True, 0.5)) is None


def test_families_cover_the_library_once_and_swaps_stay_in_them() -> None:
    from satsight.scene.material_families import LIBRARY_FAMILIES, swap_candidates
    from satsight.scene.material_library import list_materials

    listed = [name for names in LIBRARY_FAMILIES.values() for name in names]
    assert sorted(listed) == sorted(list_materials())
    assert swap_candidates("mli_gold") == (
        "aluminium_teflon", "silver_teflon", "beta_cloth", "black_kapton", "ge_black_kapton"
    )  # fmt: skip
    assert swap_candidates("library:gold") == ("aluminium", "anodised_aluminium", "silver",
                                               "titanium")  # fmt: skip
    assert swap_candidates("cfrp") == () and swap_candidates("panel_substrate") == ()


def test_the_earth_behind_is_off_the_line_of_sight_by_the_drawn_cap_angle() -> None:
    """The Earth's centre is turned from the line of sight by the cap angle of the draw's
    number (uniform over a cap of 0.8 x the Earth's angular radius from the altitude),
    towards the draw's azimuth; u = 1 reaches the cap's edge."""
    from satsight.constants import EARTH_MEAN_RADIUS_M
    from satsight.randomization.apply import earth_behind_direction
    from satsight.randomization.draws import EarthDraw

    sight = np.array([0.0, 0.0, 1.0])
    radius = math.asin(EARTH_MEAN_RADIUS_M / (EARTH_MEAN_RADIUS_M + 500e3))
    for u in (0.0, 0.3, 1.0):
        draw = EarthDraw(1.0, "uniform", 0, True, u, 1.0)
        direction, theta = earth_behind_direction(sight, 500e3, draw)
        cap = 0.8 * radius
        assert theta == pytest.approx(math.acos(1.0 - u * (1.0 - math.cos(cap))), abs=1e-12)
        assert math.acos(direction @ sight) == pytest.approx(theta, abs=1e-9)
        assert np.linalg.norm(direction) == pytest.approx(1.0, abs=1e-12)
