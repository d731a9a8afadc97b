"""A frame's light from its inputs on a grid of 2^-32 of their size: frames that share the
target's state (an RSSF plan's frames at one epoch) share one light field, bit for bit."""

from __future__ import annotations

import dataclasses
import math
import pickle
from collections import Counter

import numpy as np
import pytest

from satsight.cli import example_scenario_path
from satsight.config.scenario import load_scenario
from satsight.frame_light import (
    _on_grid,
    _R_cam_from_earth_fixed,
    frame_light,
    frame_light_inputs,
    light_from_inputs,
)
from satsight.lighting.bodies import environment_light_field
from satsight.lighting.scene_bodies import earth_body
from satsight.pipeline import LIGHT_CACHE_SIZE, FrameEngine
from satsight.poses.plan import plan_track

RSSF_FRAMES = 24
GRID = 2.0**-32


def _rssf(frames: int = RSSF_FRAMES, width_px: int | None = None):
    scenario = load_scenario(example_scenario_path().parent / "rssf_dataset.yaml")
    sampler = scenario.sampler.model_copy(update={"frame_count": frames})
    update: dict = {"sampler": sampler}
    if width_px is not None:
        camera = scenario.camera.model_copy(update={"width_px": width_px, "height_px": width_px})
        update["camera"] = camera
    return scenario.model_copy(update=update)


@pytest.fixture(scope="module")
def rssf():
    scenario = _rssf()
    mesh = scenario.target.build()
    return scenario, plan_track(scenario.plan_request(), mesh.center_m, mesh.bounding_radius_m)


def _raw_inputs(scenario, track, i: int) -> dict[str, np.ndarray]:
    """The frame's body-frame inputs as its own camera rotation gives them, off the grid."""
    R_body_from_cam = track.cam_from_body(i).R_a_from_b.T
    return {
        "sun_direction_body": R_body_from_cam @ track.sun_from_target_cam[i],
        "earth_center_body_m": R_body_from_cam
        @ (track.earth_from_target_cam[i] * track.earth_distance_m[i]),
        "moon_center_body_m": R_body_from_cam
        @ (track.moon_from_target_cam[i] * track.moon_distance_m[i]),
        "R_body_from_earth_fixed": (R_body_from_cam @ _R_cam_from_earth_fixed(track, i)).ravel(),
    }


def test_rssf_frames_at_one_epoch_share_their_light_inputs(rssf) -> None:
    scenario, track = rssf
    assert len(set(track.epoch_utc)) == 1
    inputs = Counter(frame_light_inputs(scenario, track, i) for i in range(len(track)))
    # One set of inputs (measured here: every frame); a value within 1e-15 of a step's edge
    # (about 1 frame in 10^4) would give a frame a set of its own.
    assert inputs.most_common(1)[0][1] >= len(track) - 1
    # Equal inputs are equal bit for bit (no -0.0 beside +0.0), so equal light follows.
    assert len({repr(key) for key in inputs}) == len(inputs)


def test_inputs_on_the_grid_are_the_frames_own_within_half_a_step(rssf) -> None:
    scenario, track = rssf
    for i in range(0, len(track), 5):
        inputs = frame_light_inputs(scenario, track, i)
        sizes = {"earth_center_body_m": track.earth_distance_m[i],
                 "moon_center_body_m": track.moon_distance_m[i]}  # fmt: skip
        for name, raw in _raw_inputs(scenario, track, i).items():
            on_grid = np.array(getattr(inputs, name))
            size = sizes.get(name, 1.0)
            _, exponent = math.frexp(float(size))
            step = math.ldexp(GRID, exponent)
            assert step <= 2.0 * GRID * size  # ~2e-10 relative
            np.testing.assert_array_less(np.abs(on_grid - raw), 0.5 * step * (1 + 1e-12))
            np.testing.assert_array_equal(np.round(on_grid / step) * step, on_grid)


def test_grid_rounding_is_idempotent_and_keeps_zero() -> None:
    rng = np.random.default_rng(3)
    for scale in (1.0, 7.0e6, 3.84e8, 1e-3):
        values = rng.normal(size=9) * scale
        once = _on_grid(values, scale)
        assert _on_grid(np.array(once), scale) == once
        assert np.abs(np.array(once) - values).max() <= 2.0**-32 * scale
    assert _on_grid(np.zeros(3)) == (0.0, 0.0, 0.0)
    # A value that rounds to zero from below is +0.0, like one from above.
    for tiny in (-1e-20, 1e-20, -0.0):
        assert math.copysign(1.0, _on_grid(np.array([tiny]))[0]) == 1.0


def test_light_from_the_grid_matches_the_light_from_the_raw_inputs(rssf) -> None:
    # The grid moves the inputs by ~2e-10 relative: the light field projected from the
    # frame's own inputs, as before the grid, agrees to 1e-8.
    scenario, track = rssf
    i = 7
    light = frame_light(scenario, track, i)
    inputs = frame_light_inputs(scenario, track, i)
    again = light_from_inputs(scenario, inputs)
    np.testing.assert_array_equal(light.sh_radiance_w_m2_sr, again.sh_radiance_w_m2_sr)
    np.testing.assert_array_equal(light.sun_direction_body, again.sun_direction_body)
    raw = _raw_inputs(scenario, track, i)
    earth = earth_body(
        raw["earth_center_body_m"],
        raw["R_body_from_earth_fixed"].reshape(3, 3),
        scenario.earth.albedo,
        raw["sun_direction_body"],
        inputs.irradiance_w_m2,
        albedo_map=scenario.earth.albedo_map(),
        shape=scenario.earth.shape,
    )
    reference = environment_light_field(
        raw["sun_direction_body"],
        inputs.irradiance_w_m2,
        earth_center_from_target_m=raw["earth_center_body_m"],
        earth_albedo=scenario.earth.albedo,
        moon_center_from_target_m=raw["moon_center_body_m"],
        moon_albedo=scenario.moon.albedo,
        l_max=scenario.render.sh_order,
        sun_irradiance_at_target_w_m2=inputs.at_target_w_m2,
        earth=earth,
    )
    assert np.abs(reference.sh_radiance_w_m2_sr).max() > 0.0
    np.testing.assert_allclose(
        light.sh_radiance_w_m2_sr,
        reference.sh_radiance_w_m2_sr,
        rtol=0.0,
        atol=1e-8 * np.abs(reference.sh_radiance_w_m2_sr).max(),
    )
    np.testing.assert_allclose(light.sun_direction_body, raw["sun_direction_body"], atol=3e-10)


def test_engine_projects_one_light_field_for_the_frames_of_one_state() -> None:
    engine = FrameEngine(_rssf(frames=6, width_px=48))
    frames = [engine.render(k) for k in range(4)]
    assert len({id(frame.light) for frame in frames}) <= 2
    assert len(engine._lights) == len({id(frame.light) for frame in frames})


def test_the_engine_keeps_the_newest_lights() -> None:
    engine = FrameEngine(_rssf(frames=3, width_px=32))
    track = engine.track
    made = []
    for k in range(LIGHT_CACHE_SIZE + 2):  # other Sun strengths: other inputs
        inputs = dataclasses.replace(
            frame_light_inputs(engine.scenario, track, 0), irradiance_w_m2=1000.0 + k
        )
        made.append((inputs, engine.light(inputs)))
    assert len(engine._lights) == LIGHT_CACHE_SIZE
    assert engine.light(made[-1][0]) is made[-1][1]  # kept
    assert engine.light(made[0][0]) is not made[0][1]  # dropped, made again
    # An engine that has not rendered yet pickles (as before), its lights with it.
    copy = pickle.loads(pickle.dumps(engine))
    assert len(copy._lights) == LIGHT_CACHE_SIZE


def test_a_frame_renders_the_same_bytes_alone_and_after_others() -> None:
    # The kept light field must not make a frame depend on the frames rendered before it.
    scenario = _rssf(frames=6, width_px=48)
    alone = FrameEngine(scenario).render(4)
    engine = FrameEngine(scenario)
    for k in (0, 1, 2, 3):
        engine.render(k)
    after = engine.render(4)
    assert len(engine._lights) <= 2  # the five frames shared their light
    for name in ("radiance_w_m2_sr", "depth_m", "part_id"):
        assert getattr(alone.image, name).tobytes() == getattr(after.image, name).tobytes()
    for alone_body, after_body in zip(alone.light.bodies, after.light.bodies, strict=True):
        for field in dataclasses.fields(alone_body):
            a, b = getattr(alone_body, field.name), getattr(after_body, field.name)
            if isinstance(a, np.ndarray):
                assert a.tobytes() == b.tobytes(), field.name
    assert alone.light.sh_radiance_w_m2_sr.tobytes() == after.light.sh_radiance_w_m2_sr.tobytes()
