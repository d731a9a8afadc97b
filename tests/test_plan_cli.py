"""`satsight plan` and datasets generated from frames planned from orbits."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from cli_runner import invoke_satsight, run_satsight
from satsight.cli import example_scenario_path, main
from satsight.config.scenario import load_scenario
from satsight.poses.plan import plan_track

EXAMPLES = example_scenario_path().parent
SMALL_CAMERA = {"preset": "wide_field", "width_px": 96, "height_px": 96}


# The command in this interpreter; the first test runs it as a child process, as a user does.
_satsight = invoke_satsight


def _write(tmp_path: Path, name: str, data: dict) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _example(name: str) -> dict:
    return yaml.safe_load((EXAMPLES / name).read_text(encoding="utf-8"))


@pytest.mark.parametrize(
    ("example", "frames"),
    [
        ("fly_around.yaml", 72),
        ("fly_by.yaml", 24),
        ("approach.yaml", 60),
        ("rssf_dataset.yaml", 70),
    ],
)
def test_examples_plan(example: str, frames: int) -> None:
    scenario = load_scenario(EXAMPLES / example)
    track = plan_track(scenario.plan_request(), scenario.target.build().center_m)
    assert len(track) == frames
    assert track.visible.any()


def test_plan_prints_the_table_and_writes_csv_and_plots(tmp_path: Path) -> None:
    out = tmp_path / "plan"
    example = str(EXAMPLES / "fly_around.yaml")
    result = run_satsight("plan", example, "--out", str(out), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "frame plan of 'fly-around'" in result.stdout
    assert "72 frames planned" in result.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == ["plan.csv", "range_phase.png", "trajectory_rtn.png", "visibility.png"]
    with (out / "plan.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 72
    ranges_km = np.array([float(row["range_m"]) for row in rows]) / 1e3
    assert np.all(np.abs(ranges_km - 1.0) < 0.02)


def test_plan_of_views_in_the_body_frame_has_no_trajectory(tmp_path: Path) -> None:
    out = tmp_path / "plan"
    result = _satsight("plan", str(example_scenario_path()), "--out", str(out), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert not (out / "trajectory_rtn.png").exists()
    assert (out / "range_phase.png").is_file() and (out / "plan.csv").is_file()


@pytest.fixture(scope="module")
def approach_dataset(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("approach")
    data = _example("approach.yaml")
    data["camera"] = SMALL_CAMERA
    data["sampler"] = {"kind": "sspt", "frame_count": 12}
    config = _write(root, "approach.yaml", data)
    out = root / "dataset"
    main(["generate", str(config), "--out", str(out)])
    return config, out


def test_generate_renders_the_visible_frames_of_the_plan(approach_dataset) -> None:
    config, out = approach_dataset
    scenario = load_scenario(config)
    track = plan_track(scenario.plan_request(), scenario.target.build().center_m)
    labels = json.loads((out / "labels.json").read_text(encoding="utf-8"))
    frames = labels["frames"]
    visible = np.flatnonzero(track.visible)
    assert 0 < len(visible) < len(track)  # the example's orbit crosses the Earth's shadow
    assert [f["plan_index"] for f in frames] == visible.tolist()
    assert [f["frame_index"] for f in frames] == list(range(len(visible)))
    for frame in frames:
        i = frame["plan_index"]
        np.testing.assert_allclose(frame["q_cam_from_body"], track.q_cam_from_body[i], atol=1e-12)
        np.testing.assert_allclose(frame["t_cam_from_body_m"], track.t_cam_from_body_m[i])
        assert frame["plan"]["visible"] and frame["plan"]["sunlit_fraction"] == 1.0
        assert frame["plan"]["epoch_utc"].startswith("2025-09-01T")
        assert frame["range_to_center_m"] == pytest.approx(track.range_m[i], rel=1e-9)
        assert frame["phase_angle_deg"] == pytest.approx(
            np.degrees(track.phase_angle_rad[i]), abs=1e-6
        )
    assert len(list((out / "images").iterdir())) == len(visible)


def test_skip_with_no_visible_frame_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    data = _example("fly_by.yaml")
    data["camera"] = SMALL_CAMERA
    data["visibility"] = {"on_fail": "skip", "sun_exclusion_deg": 180.0}
    config = _write(tmp_path, "blind.yaml", data)
    out = tmp_path / "never"
    result = _satsight("generate", str(config), "--out", str(out), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "none of the 24 planned frames passes the visibility tests" in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"epoch_utc": "2025-13-01T00:00:00Z"}, "month 13 outside 1-12"),
        ({"observer": None}, "sampler sspt follows the observer's trajectory"),
        ({"orbit": {"semi_major_axis_km": 6400.0}}, "semi_major_axis_km is measured from"),
        ({"sun": {"azimuth_deg": 10.0}}, "sun.azimuth_deg: with frames planned from orbits"),
        ({"frames": [{"distance_km": 1.0}]}, "not both"),
    ],
)
def test_bad_orbital_scenarios_exit_2_with_a_message(tmp_path: Path, change, message) -> None:
    data = _example("fly_around.yaml")
    for key, value in change.items():
        if value is None:
            del data[key]
        else:
            data[key] = value
    config = _write(tmp_path, "bad.yaml", data)
    result = _satsight("plan", str(config), "--out", str(tmp_path / "p"), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "p").exists()
