"""FrameEngine: one frame end to end on small images (64 px, two-wing procedural target).

Renders are seeded from the frame's plan index, so the same frame comes out the same however
often and in whatever company it is rendered; the camera mode switches at
``camera.far.switch_range_km``; the Sun's irradiance follows the inverse square of its
distance; ``finish`` turns a render into a label record and a DN image of the camera's size.
"""

from __future__ import annotations

import numpy as np
import pytest

from satsight.config.scenario import parse_scenario
from satsight.constants import AU_M
from satsight.dataset.frame_files import write_frame_files
from satsight.dataset.image_files import read_png
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import band_irradiance_w_m2
from satsight.pipeline import FrameEngine

SIZE_PX = 64
BAND_NM = (450.0, 900.0)
# The Sun-Earth distance stays within the orbit's perihelion and aphelion, in AU.
SUN_DISTANCE_RANGE_AU = (0.983, 1.017)
# Two ways of scaling the same band integral to a distance: float64 rounding only.
REL_ROUNDING = 1e-12

VIEWS = {
    "name": "engine-views",
    "seed": 5,
    "camera": {
        "preset": "high_resolution",
        "width_px": SIZE_PX,
        "height_px": SIZE_PX,
        "far": {"preset": "wide_field", "switch_range_km": 0.1},
    },
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "sun": {"azimuth_deg": 30.0, "elevation_deg": 40.0, "band_nm": list(BAND_NM),
            "distance_au": 1.5},
    "frames": [
        {"distance_km": 0.05, "azimuth_deg": 20.0, "elevation_deg": 10.0},
        {"distance_km": 0.2, "azimuth_deg": 60.0, "elevation_deg": -10.0},
        {"distance_km": 0.08, "azimuth_deg": 120.0, "elevation_deg": 30.0},
    ],
    "render": {"bounces": 0, "samples_per_pixel": 4},
}  # fmt: skip


def orbital(on_fail: str, **visibility) -> dict:
    """The fly-around example on a 64 px wide-field camera, one frame every 60 degrees."""
    return {
        "name": "engine-orbit",
        "seed": 11,
        "epoch_utc": "2025-06-21T06:00:00Z",
        "camera": {"preset": "wide_field", "width_px": SIZE_PX, "height_px": SIZE_PX},
        "target": {"procedural": {"satellite_class": "two_wings", "seed": 3}},
        "orbit": {"semi_major_axis_km": 7000.0, "eccentricity": 0.0, "inclination_deg": 97.9,
                  "raan_deg": 0.0, "arg_perigee_deg": 0.0, "true_anomaly_deg": 0.0},
        "attitude": {"law": "lvlh_fixed"},
        "observer": {"mode": "fly_around", "radius_km": 1.0, "camera_roll": "orbit_normal"},
        "sampler": {"kind": "sspt", "step_deg": 60.0},
        "visibility": {**visibility, "on_fail": on_fail},
        "sun": {"band_nm": list(BAND_NM)},
        "stars": {"enabled": False},
        "render": {"bounces": 0, "samples_per_pixel": 4},
    }  # fmt: skip


@pytest.fixture(scope="module")
def views_engine(llvm_variant) -> FrameEngine:
    return FrameEngine(parse_scenario(VIEWS, "test"))


def test_a_frame_renders_the_same_alone_twice_or_after_others(views_engine) -> None:
    first = views_engine.render(2).image.radiance_w_m2_sr.copy()
    assert np.any(first > 0), "the target is not in the frame"
    views_engine.render(0)
    views_engine.render(1)
    again = views_engine.render(2).image.radiance_w_m2_sr
    np.testing.assert_array_equal(again, first)
    # A fresh engine (new renderer, new kernels) that renders only this frame.
    alone = FrameEngine(parse_scenario(VIEWS, "test")).render(2).image.radiance_w_m2_sr
    np.testing.assert_array_equal(alone, first)


@pytest.mark.parametrize("samples_per_pixel", [1, 4])  # labels in the pass or apart
def test_an_engine_whose_outputs_hold_no_normals_renders_none(
    llvm_variant, samples_per_pixel, tmp_path
) -> None:
    """Without the normals output the engine renders no normals image (0.2 GB at 4K); the
    frame's other images and its record are those of an engine that renders them, and
    the Simulator's engine (normals=True) always has them, in float32. A dataset engine
    renders them in float16, as its file holds them: the float32 normals rounded to the
    nearest half float."""
    views = {**VIEWS, "render": {**VIEWS["render"], "samples_per_pixel": samples_per_pixel}}
    lean = FrameEngine(parse_scenario({**views, "outputs": {"files": ["dn", "masks"]}}, "t"))
    full = FrameEngine(parse_scenario(views, "test"))
    asked = FrameEngine(parse_scenario({**views, "outputs": {"files": ["dn"]}}, "t"), True)
    assert (lean.normals, full.normals, asked.normals) == (False, "half", True)
    for index in range(lean.frame_count):
        without, with_normals = lean.render(index), full.render(index)
        assert without.image.normals_cam is None
        normals = with_normals.image.normals_cam
        assert normals.shape == (SIZE_PX, SIZE_PX, 3) and normals.dtype == np.float16
        seen = with_normals.image.part_id > 0
        assert seen.any()
        unit = np.linalg.norm(normals[seen].astype(np.float64), axis=-1)
        np.testing.assert_allclose(unit, 1.0, atol=3 * 2.0**-11)  # three half-float roundings
        for name in ("radiance_w_m2_sr", "depth_m", "part_id"):
            assert np.array_equal(getattr(without.image, name), getattr(with_normals.image, name))
        lean_record, lean_arrays, _ = lean.finish(without)
        full_record, full_arrays, _ = full.finish(with_normals)
        assert lean_record == full_record
        float32 = asked.render(index).image.normals_cam
        assert float32.dtype == np.float32
        np.testing.assert_allclose(np.linalg.norm(float32[seen], axis=-1), 1.0, atol=1e-5)
        np.testing.assert_array_equal(float32.astype(np.float16), normals)
        with pytest.raises(ValueError, match="normals must be True, False or 'half'"):
            full.renderer.render(full.camera, full.track.cam_from_body(index),
                                 with_normals.light, normals="float16")  # fmt: skip
        # Frames waiting for their files keep the radiance only when a file holds it.
        kept = full_arrays.for_files(full.file_keys())
        assert kept.image.radiance_w_m2_sr is with_normals.image.radiance_w_m2_sr
        dropped = lean_arrays.for_files(lean.file_keys())
        assert dropped.image.radiance_w_m2_sr is None
        assert dropped.image.margin_radiance_w_m2_sr is None
        files, crop_files, _ = write_frame_files(
            tmp_path, index, dropped, lean.file_keys(), (3, 5, 40, 30), True
        )
        assert set(files) == set(crop_files) == set(lean.file_keys())
        np.testing.assert_array_equal(
            read_png(tmp_path / crop_files["part_mask_png16"]), without.image.part_id[5:30, 3:40]
        )


def test_frames_left_out_do_not_change_the_seeds_of_the_others(llvm_variant) -> None:
    """With on_fail: skip the dataset's frame k is plan frame plan_indices[k]; it renders as
    that plan frame does when every frame is rendered (the seed follows the plan index)."""
    skip = FrameEngine(parse_scenario(orbital("skip", max_phase_angle_deg=90.0), "test"))
    flag = FrameEngine(parse_scenario(orbital("flag", max_phase_angle_deg=90.0), "test"))
    assert 0 < skip.frame_count < flag.frame_count, "the test needs some frames left out"
    np.testing.assert_array_equal(flag.plan_indices, np.arange(flag.frame_count))
    k = skip.frame_count - 1
    plan_index = int(skip.plan_indices[k])
    assert plan_index != k
    kept = skip.render(k)
    assert (kept.frame_index, kept.plan_index) == (k, plan_index)
    np.testing.assert_array_equal(
        kept.image.radiance_w_m2_sr, flag.render(plan_index).image.radiance_w_m2_sr
    )


def test_camera_mode_switches_beyond_the_switch_range(views_engine) -> None:
    # 50 m and 80 m are within the 100 m switch range, 200 m beyond it.
    assert [views_engine.camera_mode(i) for i in range(3)] == ["primary", "far", "primary"]
    frame = views_engine.render(1)
    assert frame.camera_mode == "far"
    far_camera, _ = views_engine.modes["far"]
    assert far_camera.focal_length_m == pytest.approx(0.7)
    assert views_engine.camera.focal_length_m == pytest.approx(3.0)


def test_sun_irradiance_of_hand_placed_views_is_the_band_at_the_scenario_distance(
    views_engine,
) -> None:
    irradiance, _ = views_engine.sun_irradiance_at_camera(0)
    at_1_au = band_irradiance_w_m2(BAND_NM, "astm_e490", 1.0)
    assert irradiance == pytest.approx(at_1_au / 1.5**2, rel=REL_ROUNDING)


def test_sun_irradiance_on_an_orbit_follows_the_inverse_square_of_the_distance(
    llvm_variant,
) -> None:
    engine = FrameEngine(parse_scenario(orbital("flag"), "test"))
    at_1_au = band_irradiance_w_m2(BAND_NM, "astm_e490", 1.0)
    for plan_index in range(len(engine.track)):
        irradiance, distance_m = engine.sun_irradiance_at_camera(plan_index)
        assert distance_m == float(engine.track.sun_distance_m[plan_index])
        lo, hi = SUN_DISTANCE_RANGE_AU
        assert lo * AU_M < distance_m < hi * AU_M
        assert irradiance == pytest.approx(at_1_au * (AU_M / distance_m) ** 2, rel=REL_ROUNDING)


def test_finish_makes_the_record_and_a_dn_image_of_the_camera_size(views_engine) -> None:
    for frame_index, mode in ((0, "primary"), (1, "far")):
        frame = views_engine.render(frame_index)
        record, arrays, box = views_engine.finish(frame)
        assert box is None  # no crop in the scenario
        assert record["frame_index"] == frame_index and record["plan_index"] == frame_index
        assert record["camera_mode"] == mode
        assert record["view"] == {**VIEWS["frames"][frame_index], "roll_deg": 0.0}
        assert {"plan", "sun_direction_body", "environment_sh_radiance_w_m2_sr", "sensor"} <= set(
            record
        )
        np.testing.assert_array_equal(record["sun_direction_body"], frame.light.sun_direction_body)
        assert arrays.image is frame.image
        dn = arrays.dn_image.dn
        assert dn.shape == (SIZE_PX, SIZE_PX) and dn.dtype == np.uint16
        assert record["sensor"]["exposure_time_s"] == arrays.dn_image.exposure_time_s


def test_no_visible_frame_with_on_fail_skip_is_a_clear_error(llvm_variant) -> None:
    """A Sun exclusion of 180 degrees fails every frame."""
    scenario = parse_scenario(orbital("skip", sun_exclusion_deg=180.0), "test")
    with pytest.raises(SatsightError, match=r"none of the 6 planned frames passes the visib"):
        FrameEngine(scenario)
