"""Plan figures, table rows and CSV of a PoseTrack built from synthetic arrays."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from PIL import Image

from figure_checks import figure_pixels
from satsight.errors import SatsightError
from satsight.poses.plan_plots import (
    RANGE_PHASE_FILE,
    TRAJECTORY_FILE,
    VISIBILITY_FILE,
    has_rtn,
    time_axis,
    write_plan_plots,
)
from satsight.poses.plan_table import (
    FLAG_SHORT_NAMES,
    plan_csv_columns,
    plan_table_rows,
    write_plan_csv,
)
from satsight.poses.track import FLAG_FIELDS, PoseTrack

RTOL_CSV = 1e-9
MIN_SIDE_PX = 300


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _track(
    time_s: np.ndarray,
    rho_rtn_m: np.ndarray,
    range_m: np.ndarray,
    flags: dict[str, np.ndarray],
    interval: tuple[str, ...],
    epoch_utc: tuple[str, ...] | None = None,
) -> PoseTrack:
    n = time_s.shape[0]
    rng = np.random.default_rng(7)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    zeros = np.zeros(n, dtype=bool)
    angle = np.linspace(0.1, 3.0, n)
    return PoseTrack(
        time_s=time_s,
        epoch_utc=epoch_utc if epoch_utc is not None else ("",) * n,
        q_cam_from_body=q,
        t_cam_from_body_m=np.column_stack([0.01 * range_m, -0.02 * range_m, range_m]),
        sun_from_target_cam=_unit(np.column_stack([np.cos(angle), np.sin(angle), 0.3 + angle])),
        sun_distance_m=np.full(n, 1.496e11),
        earth_from_target_cam=_unit(rng.normal(size=(n, 3))),
        earth_distance_m=np.full(n, 7.0e6),
        moon_from_target_cam=_unit(rng.normal(size=(n, 3))),
        moon_distance_m=np.full(n, np.nan),
        rho_rtn_m=rho_rtn_m,
        range_m=range_m,
        phase_angle_rad=angle,
        sunlit_fraction=np.clip(np.linspace(-0.5, 1.5, n), 0.0, 1.0),
        los_clearance_m=np.linspace(-1.0e5, 3.0e6, n),
        sun_boresight_angle_rad=np.pi - angle,
        earth_occulted=flags.get("earth_occulted", zeros),
        eclipsed=flags.get("eclipsed", zeros),
        sun_excluded=flags.get("sun_excluded", zeros),
        phase_rejected=flags.get("phase_rejected", zeros),
        interval=interval,
        q_cam_from_gcrs=np.full((n, 4), np.nan),
        camera_position_gcrs_m=np.full((n, 3), np.nan),
        camera_velocity_gcrs_m_s=np.full((n, 3), np.nan),
    )


@pytest.fixture(scope="module")
def fly_around() -> PoseTrack:
    """An RTN fly-around ellipse over 90 min with a few frames failing each test."""
    n = 40
    theta = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    rho = 2000.0 * np.column_stack([np.sin(theta), 2.0 * np.cos(theta), 0.5 * np.sin(theta)])
    range_m = np.linalg.norm(rho, axis=1)
    flags = {name: np.zeros(n, dtype=bool) for name in FLAG_FIELDS}
    flags["earth_occulted"][[3]] = True
    flags["eclipsed"][10:16] = True
    flags["sun_excluded"][[15, 30, 31]] = True
    flags["phase_rejected"][[31, 39]] = True
    interval = tuple("5-10 km" if r > 3000.0 else "0.5-5 km" for r in range_m)
    epochs = tuple(f"2030-01-01T00:{i:02d}:00.000" for i in range(n))
    return _track(np.linspace(0.0, 5400.0, n), rho, range_m, flags, interval, epochs)


@pytest.fixture(scope="module")
def view_grid() -> PoseTrack:
    """Body-frame views: all at one instant, no orbit, ranges from 0.2 to 60 km."""
    n = 12
    range_m = np.geomspace(200.0, 60_000.0, n)
    flags = {"phase_rejected": np.arange(n) % 4 == 0}
    return _track(np.zeros(n), np.full((n, 3), np.nan), range_m, flags, ("views",) * n)


def _assert_png(path) -> None:
    assert path.is_file()
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB"))
    assert min(pixels.shape[:2]) > MIN_SIDE_PX
    packed = pixels.astype(np.uint32) @ np.array([1 << 16, 1 << 8, 1], dtype=np.uint32)
    assert np.unique(packed).size > 10, "the figure is (nearly) blank"


def test_plots_of_an_rtn_fly_around(fly_around, tmp_path) -> None:
    out_dir = tmp_path / "new" / "plots"
    paths = write_plan_plots(fly_around, out_dir, "fly-around $test$")
    assert [p.name for p in paths] == [TRAJECTORY_FILE, RANGE_PHASE_FILE, VISIBILITY_FILE]
    for path in paths:
        assert path.parent == out_dir
        _assert_png(path)


def test_plots_without_an_orbit_skip_the_trajectory(view_grid, tmp_path) -> None:
    assert not has_rtn(view_grid)
    paths = write_plan_plots(view_grid, tmp_path, "view grid")
    assert [p.name for p in paths] == [RANGE_PHASE_FILE, VISIBILITY_FILE]
    assert not (tmp_path / TRAJECTORY_FILE).exists()
    for path in paths:
        _assert_png(path)


def test_plots_refuse_an_empty_track(fly_around, tmp_path) -> None:
    empty = fly_around.select(np.zeros(len(fly_around), dtype=bool))
    with pytest.raises(SatsightError, match="no frames"):
        write_plan_plots(empty, tmp_path, "empty")


def test_time_axis_units(fly_around, view_grid) -> None:
    x, label = time_axis(fly_around)
    assert "[min]" in label
    np.testing.assert_allclose(x, fly_around.time_s / 60.0)
    x, label = time_axis(fly_around.select(np.arange(5)))
    assert "[s]" in label
    np.testing.assert_array_equal(x, fly_around.time_s[:5])
    x, label = time_axis(view_grid)
    assert label.startswith("frame index")
    np.testing.assert_array_equal(x, np.arange(len(view_grid)))


def test_table_rows_match_the_track(fly_around) -> None:
    rows = plan_table_rows(fly_around)
    assert len(rows) == len(fly_around)
    assert list(rows[0]) == [
        "frame",
        "time_s",
        "epoch_utc",
        "range_km",
        "phase_deg",
        "sunlit",
        "visible",
        "interval",
    ]
    for i, row in enumerate(rows):
        assert row["frame"] == i
        assert row["time_s"] == pytest.approx(fly_around.time_s[i], abs=0.05)
        assert row["epoch_utc"] == fly_around.epoch_utc[i]
        assert row["range_km"] == pytest.approx(fly_around.range_m[i] / 1000.0, abs=5e-4)
        assert row["phase_deg"] == pytest.approx(
            math.degrees(fly_around.phase_angle_rad[i]), abs=0.05
        )
        assert row["sunlit"] == pytest.approx(fly_around.sunlit_fraction[i], abs=5e-4)
        assert row["interval"] == fly_around.interval[i]
        failing = [FLAG_SHORT_NAMES[f] for f in FLAG_FIELDS if getattr(fly_around, f)[i]]
        assert row["visible"] == ("yes" if not failing else ",".join(failing))
    assert rows[0]["visible"] == "yes"
    assert rows[3]["visible"] == "occulted"
    assert rows[12]["visible"] == "eclipse"
    assert rows[15]["visible"] == "eclipse,sun"
    assert rows[31]["visible"] == "sun,phase"
    assert rows[39]["visible"] == "phase"


def test_table_rows_without_epochs(view_grid) -> None:
    rows = plan_table_rows(view_grid)
    assert "epoch_utc" not in rows[0]
    assert [r["visible"] for r in rows[:4]] == ["phase", "yes", "yes", "yes"]
    assert rows[0]["range_km"] == 0.2
    assert rows[-1]["range_km"] == 60.0


def _close(text: str, expected: float) -> bool:
    value = float(text)
    if np.isnan(expected):
        return np.isnan(value)
    return value == pytest.approx(expected, rel=RTOL_CSV, abs=1e-300)


@pytest.mark.parametrize("case", ["fly_around", "view_grid"])
def test_csv_round_trip(case, request, tmp_path) -> None:
    track: PoseTrack = request.getfixturevalue(case)
    path = write_plan_csv(track, tmp_path / "sub" / "plan.csv")
    with path.open(newline="", encoding="utf-8") as stream:
        reader = csv.DictReader(stream)
        assert reader.fieldnames == plan_csv_columns()
        rows = list(reader)
    assert len(rows) == len(track)
    visible = track.visible
    for i, row in enumerate(rows):
        assert int(row["frame"]) == i
        assert row["epoch_utc"] == track.epoch_utc[i]
        assert row["interval"] == track.interval[i]
        scalars = {
            "time_s": track.time_s[i],
            "range_m": track.range_m[i],
            "phase_angle_deg": math.degrees(track.phase_angle_rad[i]),
            "sunlit_fraction": track.sunlit_fraction[i],
            "los_clearance_m": track.los_clearance_m[i],
            "sun_boresight_angle_deg": math.degrees(track.sun_boresight_angle_rad[i]),
            "sun_distance_m": track.sun_distance_m[i],
            "earth_distance_m": track.earth_distance_m[i],
            "moon_distance_m": track.moon_distance_m[i],
        }
        for column, expected in scalars.items():
            assert _close(row[column], expected), column
        vectors = {
            "q_cam_from_body_{}": ("wxyz", track.q_cam_from_body[i]),
            "t_cam_from_body_{}_m": ("xyz", track.t_cam_from_body_m[i]),
            "rho_rtn_{}_m": ("rtn", track.rho_rtn_m[i]),
            "sun_from_target_cam_{}": ("xyz", track.sun_from_target_cam[i]),
            "earth_from_target_cam_{}": ("xyz", track.earth_from_target_cam[i]),
            "moon_from_target_cam_{}": ("xyz", track.moon_from_target_cam[i]),
        }
        for pattern, (components, expected) in vectors.items():
            for c, value in zip(components, expected, strict=True):
                assert _close(row[pattern.format(c)], value), pattern.format(c)
        for name in FLAG_FIELDS:
            assert row[name] == ("true" if getattr(track, name)[i] else "false")
        assert row["visible"] == ("true" if visible[i] else "false")


def test_csv_quaternion_columns_are_the_track_quaternion(fly_around, tmp_path) -> None:
    path = write_plan_csv(fly_around, tmp_path / "plan.csv")
    with path.open(newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    q = np.array([[float(r[f"q_cam_from_body_{c}"]) for c in "wxyz"] for r in rows])
    np.testing.assert_allclose(q, fly_around.q_cam_from_body, rtol=RTOL_CSV, atol=0)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, rtol=0, atol=1e-12)


def test_plots_of_a_single_frame(fly_around, tmp_path) -> None:
    one = fly_around.select(np.array([12]))
    paths = write_plan_plots(one, tmp_path, "one frame")
    assert [p.name for p in paths] == [TRAJECTORY_FILE, RANGE_PHASE_FILE, VISIBILITY_FILE]
    for path in paths:
        figure_pixels(path)  # a PNG, not blank
    assert time_axis(one)[1] == "frame index"


def test_empty_track_table_and_csv(fly_around, tmp_path) -> None:
    empty = fly_around.select(np.zeros(len(fly_around), dtype=bool))
    assert plan_table_rows(empty) == []
    path = write_plan_csv(empty, tmp_path / "empty.csv")
    with path.open(newline="", encoding="utf-8") as stream:
        assert list(csv.reader(stream)) == [plan_csv_columns()]
