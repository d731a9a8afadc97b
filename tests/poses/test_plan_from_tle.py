"""Frame plans whose target (or observer) flies a TLE with SGP4 or follows an OEM file."""

from __future__ import annotations

import copy
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import yaml

from satsight.config.scenario import load_scenario, parse_scenario
from satsight.ephemeris.oem import format_oem, read_oem
from satsight.ephemeris.time import epoch_times
from satsight.ephemeris.tle import parse_tle, tle_checksum
from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.poses.plan import plan_track

ONE_MM = 1e-3
ISS = [
    "ISS (ZARYA)",
    "1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991",
    "2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482",
]
BASE = {
    "name": "tle-plan-test",
    "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
    "tle": {"lines": ISS},
    "observer": {"mode": "fly_around", "radius_km": 1.0},
    "sampler": {"kind": "sspt", "frame_count": 24},
    "earth": {"albedo": 0.3},
}


def _scenario(**changes) -> dict:
    data = copy.deepcopy(BASE)
    for key, value in changes.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    return data


def _target_positions(track) -> np.ndarray:
    """The body origin in GCRS from the track's camera pose: r_cam + R_gcrs_from_cam t."""
    R_gcrs_from_cam = np.swapaxes(matrix_from_quaternion(track.q_cam_from_gcrs), -1, -2)
    return track.camera_position_gcrs_m + np.einsum(
        "nij,nj->ni", R_gcrs_from_cam, track.t_cam_from_body_m
    )


def _shifted_tle(mean_anomaly_deg: str) -> list[str]:
    """The ISS set with another mean anomaly (columns 44-51), checksum recomputed."""
    line2 = ISS[2][:43] + mean_anomaly_deg.rjust(8) + ISS[2][51:68]
    return ["CHASER", ISS[1], line2 + str(tle_checksum(line2))]


def test_epoch_defaults_to_the_tle_epoch() -> None:
    scenario = parse_scenario(_scenario())
    assert scenario.epoch_utc == parse_tle(ISS)[0].epoch_utc
    explicit = parse_scenario(_scenario(epoch_utc="2019-12-10T00:00:00Z"))
    assert explicit.epoch_utc == "2019-12-10T00:00:00Z"


def test_fly_around_target_follows_sgp4() -> None:
    scenario = parse_scenario(_scenario())
    track = plan_track(scenario.plan_request(), np.zeros(3), target_radius_m=5.0)
    r_sgp4, _ = parse_tle(ISS)[0].state_gcrs(epoch_times(scenario.epoch_utc, track.time_s))
    assert np.max(np.linalg.norm(_target_positions(track) - r_sgp4, axis=1)) < ONE_MM
    # The relative orbit rides on the SGP4 trajectory: its range stays near 1 km over the
    # target orbit (as for element targets: within 1 %), instead of drifting by kilometres.
    assert np.all(np.abs(track.range_m - 1000.0) < 10.0)
    # One frame per 1/24 of the SGP4 mean-motion period.
    period = parse_tle(ISS)[0].period_s
    assert track.time_s[1] == pytest.approx(period / 24, rel=1e-3)


@pytest.mark.parametrize(
    "observer",
    [
        {"mode": "fly_by", "miss_distance_km": 0.5, "start_along_track_km": 2.0},
        {"mode": "hover", "range_km": 2.0},
        {"mode": "relative_rtn", "position_rtn_km": [0.0, -1.5, 0.0]},
        {"mode": "approach", "start_range_km": 5.0, "end_range_km": 0.5},
    ],
)
def test_relative_modes_with_a_tle_target(observer: dict) -> None:
    scenario = parse_scenario(
        _scenario(
            observer=observer, sampler={"kind": "sspt", "frame_count": 9, "duration_s": 1800.0}
        )
    )
    track = plan_track(scenario.plan_request(), np.zeros(3), target_radius_m=5.0)
    r_sgp4, _ = parse_tle(ISS)[0].state_gcrs(epoch_times(scenario.epoch_utc, track.time_s))
    assert np.max(np.linalg.norm(_target_positions(track) - r_sgp4, axis=1)) < ONE_MM
    assert np.all(track.range_m < 6000.0)


def test_observer_on_its_own_tle() -> None:
    chaser = _shifted_tle("85.6498")  # 0.01 degree ahead: about 1.2 km
    scenario = parse_scenario(
        _scenario(
            observer={"mode": "tle", "lines": chaser},
            sampler={"kind": "sspt", "frame_count": 5, "duration_s": 600.0},
        )
    )
    track = plan_track(scenario.plan_request(), np.zeros(3), target_radius_m=5.0)
    times = epoch_times(scenario.epoch_utc, track.time_s)
    r_chaser, _ = parse_tle(chaser)[0].state_gcrs(times)
    assert np.max(np.linalg.norm(track.camera_position_gcrs_m - r_chaser, axis=1)) < ONE_MM
    assert np.all((track.range_m > 1000.0) & (track.range_m < 1500.0))


def test_rssf_with_a_tle_target() -> None:
    scenario = parse_scenario(_scenario(observer=None, sampler={"kind": "rssf", "frame_count": 7}))
    track = plan_track(scenario.plan_request(), np.zeros(3), target_radius_m=5.0)
    r_sgp4, _ = parse_tle(ISS)[0].state_gcrs(epoch_times(scenario.epoch_utc, [0.0]))
    assert np.max(np.linalg.norm(_target_positions(track) - r_sgp4, axis=1)) < ONE_MM


def test_oem_target_equals_its_interpolation(tmp_path: Path) -> None:
    iss = parse_tle(ISS)[0]
    times = epoch_times("2019-12-09T16:40:00Z", np.arange(0.0, 7201.0, 60.0))
    r, v = iss.state_gcrs(times)
    (tmp_path / "target.oem").write_text(
        format_oem(times, r, v, object_name="ISS", object_id="1998-067A", degree=5)
    )
    data = _scenario(
        tle=None,
        oem={"file": "target.oem"},
        sampler={"kind": "sspt", "frame_count": 7, "duration_s": 3600.0},
    )
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(data))
    scenario = load_scenario(tmp_path / "scenario.yaml")  # the file is found beside it
    assert scenario.epoch_utc == "2019-12-09T16:40:00.000000Z"
    track = plan_track(scenario.plan_request(), np.zeros(3), target_radius_m=5.0)
    ephemeris = read_oem(tmp_path / "target.oem")
    r_oem, _ = ephemeris.state_gcrs(epoch_times(scenario.epoch_utc, track.time_s))
    assert np.max(np.linalg.norm(_target_positions(track) - r_oem, axis=1)) < ONE_MM


def test_bundled_tle_and_oem_examples_plan() -> None:
    folder = Path(str(resources.files("satsight") / "examples"))
    for name in ("tle_iss_fly_around.yaml", "oem_iss_hover.yaml"):
        track = plan_track(
            load_scenario(folder / name).plan_request(), np.zeros(3), target_radius_m=5.0
        )
        assert np.all(np.abs(track.range_m - 1000.0) < 10.0)


def test_errors() -> None:
    with pytest.raises(SatsightError, match=r"give the target's trajectory once"):
        parse_scenario(_scenario(orbit={"semi_major_axis_km": 7000.0}))
    with pytest.raises(SatsightError, match=r"needs orbit \(or tle, omm, oem\)"):
        parse_scenario(_scenario(tle=None, epoch_utc="2019-12-09T00:00:00Z"))
    with pytest.raises(SatsightError, match=r"column 69: checksum"):
        parse_scenario(_scenario(tle={"lines": [ISS[1], ISS[2][:68] + "0"]}))
    with pytest.raises(SatsightError, match=r"exactly one of 'lines'"):
        parse_scenario(_scenario(tle={"lines": ISS[1:], "file": "x.tle"}))
    late = parse_scenario(_scenario(epoch_utc="2020-01-20T00:00:00Z"))
    with pytest.raises(SatsightError, match=r"refused beyond 30 days"):
        plan_track(late.plan_request(), np.zeros(3), target_radius_m=5.0)
    with pytest.raises(SatsightError, match=r"OEM file not found"):
        parse_scenario(
            _scenario(
                tle=None, oem={"file": "/nonexistent/x.oem"}, epoch_utc="2019-12-09T00:00:00Z"
            )
        )
