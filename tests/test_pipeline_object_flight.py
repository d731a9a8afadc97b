"""An object on its own flight, end to end on small frames (96 px, 41° field).

The camera hovers 50 m ahead of the target; a 2 m plate starts 25 m ahead of the target
(between the two) drifting across the line of sight. On every frame:

- its pose label agrees, to 1 mm, with an independent construction from the inertial
  states: the plate flown from its RTN start, seen from the camera's planned position and
  attitude in GCRS (the renderer's route goes through the target's body frame instead);
- its visible pixels are centred where that position projects (0.5 px);
- it moves across the image between frames and, where it passes before the target, hides
  part of it.

With a 0.2 s exposure and motion blur on, the plate flying at 20 m/s across the line of
sight is drawn at each time sample: its light spreads beyond its mid-exposure silhouette
by the smear |v| (tau_last - tau_first) / range x f / pitch (10.7 px), and its total is
kept.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from satsight.config.scenario import parse_scenario
from satsight.ephemeris.orbits import propagate, state_from_elements
from satsight.frames.orbital import inertial_from_relative_rtn
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.pipeline import FrameEngine

SIZE_PX = 96
FOCAL_M = 0.002
PITCH_M = 15e-6
ONE_MM = 1e-3
PLATE_START_RTN_M = [0.0, 25.0, -3.0]
# Object axes are LVLH (x = T, y = -N, z = -R) under the identity offset: a quarter turn
# about y puts the plate's normal (+z) along T, facing the camera ahead.
FACING_T = [float(np.cos(np.pi / 4)), 0.0, float(np.sin(np.pi / 4)), 0.0]

BASE = {
    "name": "object-flight",
    "seed": 5,
    "epoch_utc": "2025-06-21T06:00:00Z",
    "camera": {"preset": "high_resolution", "width_px": SIZE_PX, "height_px": SIZE_PX,
               "focal_length_m": FOCAL_M, "pixel_pitch_um": PITCH_M * 1e6,
               "optics": {"aperture_diameter_m": 0.001},
               "exposure": {"mode": "fixed", "time_s": 0.001}},
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "orbit": {"semi_major_axis_km": 7000.0, "inclination_deg": 51.6, "raan_deg": 20.0},
    "observer": {"mode": "hover", "range_km": 0.05},
    "sampler": {"kind": "sspt", "frame_count": 3, "start_s": 0.0, "duration_s": 60.0},
    "visibility": {"on_fail": "keep"},
    "render": {"bounces": 0, "samples_per_pixel": 1, "environment": "off",
               "motion_blur": False},
    "stars": {"enabled": False},
}  # fmt: skip


def _plate_obj(folder) -> str:
    path = folder / "plate.obj"
    path.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    return str(path)


def _scenario(folder, velocity_rtn_m_s, **changes):
    data = copy.deepcopy(BASE)
    data.update(changes)
    data["objects"] = [
        {
            "name": "plate",
            "mesh": {"path": _plate_obj(folder), "materials": {"plate": "lambert_white"}},
            "flight": {
                "position_rtn_m": PLATE_START_RTN_M,
                "velocity_rtn_m_s": velocity_rtn_m_s,
                "attitude": {"law": "lvlh_fixed", "q_ref_from_body": FACING_T},
            },
        }
    ]
    return parse_scenario(data, "test")


def _plate_in_camera_m(scenario, engine, plan_index: int) -> np.ndarray:
    """The plate's origin in the camera frame from the inertial states alone."""
    track = engine.track
    t = track.time_s[plan_index]
    r0, v0 = state_from_elements(scenario.orbit.build())
    flight = scenario.objects[0].flight
    start = inertial_from_relative_rtn(r0, v0, np.array(flight.position_rtn_m),
                                       np.array(flight.velocity_rtn_m_s))  # fmt: skip
    r, _ = propagate(*start, np.array([t]), j2=True, epoch=scenario.epoch_utc)
    R_cam_from_gcrs = matrix_from_quaternion(track.q_cam_from_gcrs[plan_index])
    return R_cam_from_gcrs @ (r[0] - track.camera_position_gcrs_m[plan_index])


@pytest.fixture(scope="module")
def drifting(llvm_variant, tmp_path_factory):
    scenario = _scenario(tmp_path_factory.mktemp("plate"), [0.0, 0.0, 0.05])
    engine = FrameEngine(scenario)
    frames = [engine.finish(engine.render(i)) for i in range(engine.frame_count)]
    return scenario, engine, frames


def test_a_flying_plates_pose_label_matches_its_inertial_flight(drifting) -> None:
    scenario, engine, frames = drifting
    for record, _, _ in frames:
        (plate,) = record["objects"]
        expected = _plate_in_camera_m(scenario, engine, record["plan_index"])
        assert np.linalg.norm(np.array(plate["t_cam_from_object_m"]) - expected) < ONE_MM


def test_a_flying_plate_is_drawn_where_it_is_and_moves_across_the_frames(drifting) -> None:
    _, engine, frames = drifting
    centres = []
    hidden = []
    for record, arrays, _ in frames:
        (plate,) = record["objects"]
        v, u = np.nonzero(arrays.object_id == 2)
        assert u.size > 100
        projected = engine.camera.project(np.array([plate["t_cam_from_object_m"]]))[0]
        # Pixel centres are at whole pixel coordinates (principal point (W - 1) / 2). The
        # centroid of the pixel centres inside a square is its centre within 0.5 px.
        centre = np.array([u.mean(), v.mean()])
        assert np.linalg.norm(centre - projected) < 0.5
        centres.append(centre)
        hidden.append(record["occlusion"]["amodal_pixel_count"]
                      - record["occlusion"]["visible_pixel_count"])  # fmt: skip
    assert np.linalg.norm(centres[-1] - centres[0]) > 5.0
    assert max(hidden) > 0  # it passes before the target


FAST_M_S, LONG_EXPOSURE_S = 20.0, 0.2


def _fast_plate(folder, motion_blur):
    """One frame of the plate crossing at FAST_M_S, exposed LONG_EXPOSURE_S: the scenario,
    its engine and the rendered frame."""
    camera = {**BASE["camera"], "exposure": {"mode": "fixed", "time_s": LONG_EXPOSURE_S}}
    render = {**BASE["render"], "motion_blur": motion_blur}
    scenario = _scenario(
        folder, [0.0, 0.0, FAST_M_S], camera=camera, render=render,
        sampler={"kind": "sspt", "frame_count": 1, "start_s": 0.0, "duration_s": 1.0},
    )  # fmt: skip
    engine = FrameEngine(scenario)
    return scenario, engine, engine.render(0)


def test_motion_blur_draws_a_fast_plate_at_its_time_samples(llvm_variant, tmp_path) -> None:
    speed_m_s = FAST_M_S
    _, engine, frame = _fast_plate(tmp_path, True)
    record, arrays, _ = engine.finish(frame)
    offsets = frame.motion.offsets_s
    assert frame.motion.sample_count == len(offsets) >= 2
    (plate,) = record["objects"]
    range_m = plate["t_cam_from_object_m"][2]
    # The outermost samples sit (n - 1) / n of the exposure apart.
    smear_px = speed_m_s * (offsets[-1] - offsets[0]) / range_m * FOCAL_M / PITCH_M
    plate_rows = np.unique(np.nonzero(arrays.object_id == 2)[0])
    radiance = arrays.image.radiance_w_m2_sr.sum(axis=-1)[plate_rows]
    ids = arrays.object_id[plate_rows]
    lit = (radiance > 0) & (ids != 1)  # the plate's light, the (still) target's left out
    lit_cols = np.nonzero(lit.any(axis=0))[0]
    still_cols = np.nonzero((ids == 2).any(axis=0))[0]
    spread_px = np.ptp(lit_cols) - np.ptp(still_cols)
    # Pixel centres sample each displaced edge: +-1 px of the continuous smear.
    assert abs(spread_px - smear_px) < 1.5
    # The samples draw the whole plate, each half as bright: the light is conserved (the
    # plate covers 110 +- 11 pixel centres at any offset).
    lit_plate = radiance[ids == 2].mean() * 2  # a still pixel holds one sample of two
    assert radiance[lit].sum() == pytest.approx(lit_plate * (ids == 2).sum(), rel=0.1)


def test_randomised_materials_keep_the_flying_plate(drifting, tmp_path) -> None:
    """A frame of randomised materials places the flying plate as the plain frame does
    (materials change no geometry), and it is still recorded."""
    scenario, _, frames = drifting
    data = scenario.model_dump(mode="json", exclude_none=True)
    varied = FrameEngine(parse_scenario({**data, "randomize": {"materials": True}}, "test"))
    record, arrays, _ = varied.finish(varied.render(2))
    plain_record, plain_arrays, _ = frames[2]
    assert "materials" in record["randomized"]
    assert np.array_equal(arrays.object_id, plain_arrays.object_id)
    assert record["objects"] == plain_record["objects"]


def test_an_object_far_out_of_view_changes_no_pixel(drifting, tmp_path) -> None:
    """A second satellite on its own orbit, thousands of kilometres away, is left out of
    every frame's geometry (``FrameView``): the radiance, depth and part ids equal those
    of the scenario without it, byte for byte, and its record shows no pixels."""
    scenario, _, _ = drifting
    data = scenario.model_dump(mode="json", exclude_none=True)
    far_orbit = {**BASE["orbit"], "raan_deg": 80.0}
    data["objects"] = [
        {"name": "far", "procedural": {"satellite_class": "tango"}, "flight": {"orbit": far_orbit}}
    ]
    with_far = FrameEngine(parse_scenario(data, "test"))
    alone = FrameEngine(parse_scenario({**data, "objects": []}, "test"))
    for i in range(with_far.frame_count):
        frame = with_far.render(i)
        record, _, _ = with_far.finish(frame)
        plain = alone.render(i).image
        distance = np.linalg.norm(record["objects"][0]["t_cam_from_object_m"])
        assert distance > 1e6
        assert record["objects"][0]["pixel_count"] == 0
        assert np.array_equal(frame.image.radiance_w_m2_sr, plain.radiance_w_m2_sr)
        assert np.array_equal(frame.image.depth_m, plain.depth_m)
        assert np.array_equal(frame.image.part_id, plain.part_id)


def test_a_fast_plate_beside_a_still_target_asks_for_time_samples(llvm_variant, tmp_path) -> None:
    """``motion_blur: auto`` measures the flying objects in view too: the target hovers
    still, the plate crosses at 20 m/s, so the frame is blurred with the samples its corners'
    path asks for (path = |v| T / range x f / pitch, 0.5 px apart)."""
    scenario, _, frame = _fast_plate(tmp_path, "auto")
    plate_cam = (frame.cam_from_body @ frame.scene.target_from_object[0]).t_a_from_b_m
    expected_px = FAST_M_S * LONG_EXPOSURE_S / plate_cam[2] * FOCAL_M / PITCH_M
    assert frame.motion is not None
    assert frame.motion.path_px == pytest.approx(expected_px, rel=0.05)
    assert frame.motion.sample_count == min(32, int(np.ceil(frame.motion.path_px / 0.5)))
    # Without the plate the target alone does not move enough to be blurred.
    still = FrameEngine(parse_scenario({**scenario.model_dump(mode="json", exclude_none=True),
                                        "objects": []}, "test"))  # fmt: skip
    assert still.render(0).motion is None
