"""Scenario keys of frames planned from orbits: what is accepted, what is refused and why."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from satsight.config.scenario import parse_scenario
from satsight.errors import SatsightError

BASE = {
    "epoch_utc": "2025-06-21T06:00:00Z",
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "orbit": {"semi_major_axis_km": 7000.0, "inclination_deg": 97.9},
    "observer": {"mode": "fly_around", "radius_km": 1.0},
    "sampler": {"kind": "sspt", "frame_count": 10},
}


def _with(**changes) -> dict:
    data = copy.deepcopy(BASE)
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    return data


def _error(data: dict) -> str:
    with pytest.raises(SatsightError, match=r"^test\.yaml: the scenario is not valid:\n") as info:
        parse_scenario(data, "test.yaml")
    return str(info.value)


def test_defaults_and_unit_conversions() -> None:
    scenario = parse_scenario(
        _with(
            attitude={"law": "spinning", "rate_body_deg_s": [0.0, 0.0, 6.0]},
            visibility={"atmosphere_margin_km": 50.0, "sun_exclusion_deg": 45.0},
        )
    )
    elements = scenario.orbit.build()
    assert elements.semi_major_axis_m == 7000e3
    assert elements.inclination_rad == pytest.approx(math.radians(97.9), rel=1e-15)
    assert scenario.observer.camera_roll == "orbit_normal"
    np.testing.assert_allclose(scenario.attitude.rate_body_rad_s, [0, 0, math.radians(6.0)])
    limits = scenario.visibility.limits()
    assert limits.atmosphere_margin_m == 50e3
    assert limits.sun_exclusion_rad == pytest.approx(math.pi / 4, rel=1e-15)
    assert limits.max_phase_angle_rad == pytest.approx(math.radians(150.0), rel=1e-15)
    assert scenario.visibility.on_fail == "flag"
    assert scenario.propagation.method == "rk4" and scenario.propagation.step_s == 1.0
    rssf = parse_scenario(_with(observer=None, sampler={"kind": "rssf", "frame_count": 7}))
    assert rssf.sampler.seed == 5  # the paper's seed
    assert rssf.sampler.intervals_km[0] == (50, 40) and rssf.sampler.include_hover


@pytest.mark.parametrize(
    ("data", "where", "message"),
    [
        (_with(sampler=None), "(top level)", "no frames"),
        (_with(orbit=None), "(top level)", "needs orbit"),
        (_with(epoch_utc=None, orbit=None), "(top level)", "needs epoch_utc and orbit"),
        (_with(epoch_utc="yesterday"), "epoch_utc", "not a valid UTC ISO-8601 time"),
        (_with(observer=None), "(top level)", "add an 'observer' with a mode"),
        (
            _with(sampler={"kind": "rssf", "frame_count": 5}),
            "(top level)",
            "rssf places the camera itself",
        ),
        (_with(sampler={"kind": "sspt"}), "sampler.sspt", "exactly one of frame_count"),
        (
            _with(sampler={"kind": "sspt", "frame_count": 3, "step_s": 10}),
            "sampler.sspt",
            "(got frame_count, step_s)",
        ),
        (
            _with(
                observer={"mode": "hover"},
                sampler={"kind": "sspt", "step_deg": 5},
            ),
            "(top level)",
            "step_deg applies only to observer mode fly_around",
        ),
        (_with(sampler={"kind": "walk"}), "sampler", "'sspt', 'rssf'"),
        (_with(observer={"mode": "orbit_around"}), "observer", "'fly_around'"),
        (_with(observer={"mode": "fly_around"}), "observer.fly_around.radius_km", "required"),
        (
            _with(observer={"mode": "fly_by", "miss_distance_km": 1, "start_along_track_km": -3}),
            "observer.fly_by",
            "never passes the target",
        ),
        (
            _with(observer={"mode": "approach", "start_range_km": 1, "end_range_km": 2}),
            "observer.approach",
            "end_range_km must be smaller",
        ),
        (
            _with(orbit={"semi_major_axis_km": 6400.0}),
            "orbit",
            "below 6478.1 km",
        ),
        (
            _with(orbit={"semi_major_axis_km": 7000.0, "eccentricity": 1.2}),
            "orbit.eccentricity",
            "less than 1",
        ),
        (
            _with(attitude={"q_ref_from_body": [1, 1, 0, 0]}),
            "attitude",
            "must be a unit quaternion",
        ),
        (
            _with(attitude={"law": "inertial", "rate_body_deg_s": [0, 0, 1]}),
            "attitude",
            "applies only to law: spinning",
        ),
        (
            _with(
                observer=None, sampler={"kind": "rssf", "frame_count": 5, "intervals_km": [[5, 10]]}
            ),
            "sampler.rssf",
            "far > near > 0",
        ),
        (
            _with(visibility={"min_phase_angle_deg": 90, "max_phase_angle_deg": 60}),
            "visibility",
            "must not exceed",
        ),
        (_with(visibility={"on_fail": "drop"}), "visibility.on_fail", "'flag', 'skip' or 'keep'"),
        (_with(earth={"altitude_km": 600}), "(top level)", "earth.altitude_km"),
        (_with(moon={"distance_km": 4e5}), "(top level)", "moon.distance_km"),
        (_with(sun={"elevation_deg": 10}), "(top level)", "sun.elevation_deg"),
    ],
)
def test_refused_with_a_message_naming_the_key(data: dict, where: str, message: str) -> None:
    text = _error(data)
    line = next((ln for ln in text.splitlines() if message in ln), None)
    assert line is not None, text
    assert line.strip().startswith(f"- {where}"), text


def test_orbital_keys_without_a_sampler_are_refused() -> None:
    data = {
        "target": BASE["target"],
        "frames": [{"distance_km": 1.0}],
        "orbit": BASE["orbit"],
        "visibility": {"on_fail": "skip"},
    }
    text = _error(data)
    assert "orbit, visibility only apply to frames planned from orbits" in text


def test_albedos_stay_allowed_with_planned_frames() -> None:
    scenario = parse_scenario(_with(earth={"albedo": 0.35}, moon={"albedo": 0.1}))
    assert scenario.earth.albedo == 0.35 and scenario.moon.albedo == 0.1


@pytest.mark.parametrize(
    "name", ["first_light", "fly_around", "fly_by", "approach", "rssf_dataset"]
)
def test_a_complete_copy_reads_back_the_same(name: str) -> None:
    """Datasets keep scenario.yaml with every default written out; it must load again."""
    from satsight.cli import example_scenario_path
    from satsight.config.scenario import load_scenario

    scenario = load_scenario(example_scenario_path().parent / f"{name}.yaml")
    copy_text = yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False)
    assert parse_scenario(yaml.safe_load(copy_text)) == scenario


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {
                "observer": {
                    "mode": "fly_by",
                    "miss_distance_km": 1e-6,
                    "start_along_track_km": 5.0,
                }
            },
            "beyond the 31622400 s (366 days) allowed",
        ),
        ({"sampler": {"kind": "sspt", "step_s": 0.001}}, "more than 1000000"),
        ({"sampler": {"kind": "sspt", "frame_count": 2, "start_s": 1e12}}, "sampler.sspt.start_s"),
        (
            {"observer": {"mode": "fly_by", "miss_distance_km": -7000, "start_along_track_km": -1}},
            "observer.fly_by.miss_distance_km",
        ),
        (
            {"observer": {"mode": "relative_rtn", "position_rtn_km": [0, 2000, 0]}},
            "within 1000 km of the target",
        ),
    ],
)
def test_plans_too_long_large_or_far_are_refused(changes: dict, message: str) -> None:
    assert message in _error(_with(**changes))
