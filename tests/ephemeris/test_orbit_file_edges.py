"""Orbit files at their edges: OEM states that do not cover the declared span, gaps between
states, impossible dates, mixed state lines, and OMM / TLE values that SGP4 cannot take.

Each case is refused with one line naming the file, the line (or record) and the field, and
what to do; at the command line the exit status is 2, there is no traceback, and a plan
written before is left as it was. The OEM truth is a circular Keplerian orbit (as in
test_oem.py), whose interpolation error with 60 s steps and degree 7 is far below a
centimetre, so the positions on both sides of a gap can be checked against it.
"""

from __future__ import annotations

import json
import logging
import math
import shutil
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from cli_runner import invoke_satsight, run_satsight
from iss_elements import ISS_1, ISS_2, ISS_OMM_FIELDS
from satsight.ephemeris.oem import format_oem, parse_oem
from satsight.ephemeris.oem_ephemeris import GAP_FACTOR
from satsight.ephemeris.omm import parse_omm
from satsight.ephemeris.orbits import MU_EARTH_M3_S2
from satsight.ephemeris.time import timescale
from satsight.ephemeris.tle import parse_tle, select_orbit, tle_checksum
from satsight.errors import SatsightError

RADIUS_M = 7000e3
OMEGA = math.sqrt(MU_EARTH_M3_S2 / RADIUS_M**3)
FIVE_CM = 0.05
EXAMPLES = Path(str(resources.files("satsight") / "examples"))
ISS_OEM = "iss_2019-12-09.oem"

ISS_OMM = ISS_OMM_FIELDS


# --- helpers ---------------------------------------------------------------------------------


def _truth(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    phase = OMEGA * t_s
    ci, si = math.cos(0.9), math.sin(0.9)
    r = RADIUS_M * np.stack([np.cos(phase), np.sin(phase) * ci, np.sin(phase) * si], -1)
    v = RADIUS_M * OMEGA * np.stack([-np.sin(phase), np.cos(phase) * ci, np.cos(phase) * si], -1)
    return r, v


def _times(seconds):
    return timescale().utc(2025, 6, 21, 6, 0, np.asarray(seconds, dtype=np.float64))


def _oem(seconds: np.ndarray, interpolation: str = "LAGRANGE", degree: int = 7) -> str:
    r, v = _truth(seconds)
    return format_oem(
        _times(seconds), r, v, object_name="TEST", object_id="2025-001A",
        interpolation=interpolation, degree=degree,
    )  # fmt: skip


def _line_of(text: str, start: str) -> int:
    """The 1-based number of the first line of ``text`` starting with ``start``."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if line.startswith(start))


def _scenario(folder: Path, oem_name: str, extra: str = "", duration_s: float = 3600.0) -> Path:
    """A hover scenario following ``oem_name`` in ``folder`` (the bundled example's layout)."""
    path = folder / "scenario.yaml"
    path.write_text(
        f"""name: edge
seed: 1
{extra}
target:
  procedural:
    satellite_class: two_wings_dish
    seed: 3
oem:
  file: {oem_name}
observer:
  mode: hover
  range_km: 1.0
sampler:
  kind: sspt
  duration_s: {duration_s}
  frame_count: 13
""",
        encoding="utf-8",
    )
    return path


def _plan(folder: Path, scenario: Path, run=invoke_satsight):
    """``satsight plan`` in this interpreter (``run_satsight``: in a child process)."""
    return run("plan", str(scenario), "--no-plots", "--out", "plan", cwd=folder)


def _assert_refused(result, *fragments: str) -> str:
    """Exit status 2, no traceback, and an 'error:' message holding every fragment."""
    assert result.returncode == 2, result.stdout + result.stderr
    output = result.stdout + result.stderr
    assert "Traceback" not in output
    message = next(line for line in output.splitlines() if "error" in line or " - " in line)
    for fragment in fragments:
        assert fragment in output, (fragment, output)
    return message


def _iss_lines() -> list[str]:
    return (EXAMPLES / ISS_OEM).read_text(encoding="utf-8").splitlines()


# --- 1. declared span wider than the states --------------------------------------------------


def test_start_time_before_first_state_defaults_to_the_first_state(caplog) -> None:
    seconds = np.arange(2400.0, 2400.0 + 3600.0 + 1.0, 60.0)
    text = _oem(seconds).replace(
        "START_TIME = 2025-06-21T06:40:00.000000", "START_TIME = 2025-06-21T06:00:00.000000"
    )
    with caplog.at_level(logging.WARNING, logger="satsight.ephemeris.oem_segments"):
        ephemeris = parse_oem(text, source="early.oem")
    start_line = _line_of(text, "START_TIME")
    assert f"early.oem, line {start_line}: START_TIME" in caplog.text
    assert "precedes the segment's first state" in caplog.text
    # The default epoch is the first state, not START_TIME.
    assert ephemeris.useable_start_utc == "2025-06-21T06:40:00.000000Z"
    r, _ = ephemeris.state_gcrs(ephemeris.useable_start)
    assert np.linalg.norm(r[0] - _truth(np.array([2400.0]))[0][0]) < 1e-3
    # START_TIME itself (40 min before the first state) is refused, never extrapolated.
    for before in (0.0, 1200.0, 2399.0):
        with pytest.raises(SatsightError) as error:
            ephemeris.state_gcrs(_times([before]))
        assert "lies outside the ephemeris's useable span(s) 2025-06-21T06:40:00.000Z to " in str(
            error.value
        )
        assert "2025-06-21T07:40:00.000Z" in str(error.value)
        assert "never extrapolated" in str(error.value)


def test_stop_time_after_last_state_refuses_times_past_it(caplog) -> None:
    seconds = np.arange(0.0, 1800.0 + 1.0, 60.0)
    text = _oem(seconds).replace(
        "STOP_TIME = 2025-06-21T06:30:00.000000", "STOP_TIME = 2025-06-21T07:00:00.000000"
    )
    with caplog.at_level(logging.WARNING, logger="satsight.ephemeris.oem_segments"):
        ephemeris = parse_oem(text)
    assert "follows the segment's last state" in caplog.text
    ephemeris.state_gcrs(_times([1800.0]))
    with pytest.raises(SatsightError, match=r"06:30:01.000Z \(UTC\) lies outside"):
        ephemeris.state_gcrs(_times([1801.0]))


def test_useable_span_without_states_is_refused_naming_its_line() -> None:
    seconds = np.arange(2400.0, 3000.0 + 1.0, 60.0)
    text = _oem(seconds).replace(
        "START_TIME = 2025-06-21T06:40:00.000000",
        "START_TIME = 2025-06-21T06:00:00.000000\n"
        "USEABLE_START_TIME = 2025-06-21T06:00:00\nUSEABLE_STOP_TIME = 2025-06-21T06:30:00",
    )
    line = _line_of(text, "USEABLE_START_TIME")
    with pytest.raises(SatsightError, match=rf"OEM, line {line}: USEABLE_START_TIME - .* holds "):
        parse_oem(text)


def test_cli_epoch_defaults_to_first_state_and_an_earlier_epoch_is_refused(
    tmp_path: Path,
) -> None:
    lines = _iss_lines()
    early = [
        "START_TIME = 2019-12-09T16:00:00.000000" if x.startswith("START_TIME") else x
        for x in lines
    ]
    (tmp_path / "early.oem").write_text("\n".join(early) + "\n", encoding="utf-8")
    shutil.copy(EXAMPLES / ISS_OEM, tmp_path / ISS_OEM)
    # The same states with an earlier START_TIME plan the same frames as the original.
    good = _plan(tmp_path, _scenario(tmp_path, "early.oem"))
    assert good.returncode == 0, good.stderr
    assert "time after 2019-12-09T16:40:00" in good.stdout
    assert "precedes the segment's first state" in good.stderr
    planned = (tmp_path / "plan" / "plan.csv").read_bytes()
    original = tmp_path / "original"
    original.mkdir()
    shutil.copy(EXAMPLES / ISS_OEM, original / ISS_OEM)
    assert _plan(original, _scenario(original, ISS_OEM)).returncode == 0
    assert (original / "plan" / "plan.csv").read_bytes() == planned
    # epoch_utc at START_TIME: refused with the states' span; the earlier plan is kept.
    scenario = _scenario(tmp_path, "early.oem", extra='epoch_utc: "2019-12-09T16:00:00Z"')
    for _ in range(2):
        bad = _plan(tmp_path, scenario)
        _assert_refused(
            bad,
            "early.oem: 2019-12-09T16:00:00.000Z (UTC) lies outside",
            "2019-12-09T16:40:00.000Z to 2019-12-09T18:40:00.000Z",
        )
        assert (tmp_path / "plan" / "plan.csv").read_bytes() == planned


# --- 2. gaps between states ------------------------------------------------------------------


@pytest.mark.parametrize(("interpolation", "degree"), [("LAGRANGE", 7), ("HERMITE", 7)])
def test_time_in_a_gap_is_refused_and_both_sides_stay_accurate(
    interpolation: str, degree: int, caplog
) -> None:
    seconds = np.arange(0.0, 3 * 3600.0 + 1.0, 60.0)
    kept = seconds[(seconds <= 3600.0) | (seconds >= 3600.0 + 2400.0)]  # a 40-minute hole
    text = _oem(kept, interpolation, degree)
    with caplog.at_level(logging.WARNING, logger="satsight.ephemeris.oem_segments"):
        ephemeris = parse_oem(text, source="gap.oem")
    before = _line_of(text, "2025-06-21T07:00:00")
    after = _line_of(text, "2025-06-21T07:40:00")
    assert "1 gap(s)" in caplog.text and f"lines {before} and {after}" in caplog.text
    for inside in (3601.0, 4800.0, 5999.0):
        with pytest.raises(SatsightError) as error:
            ephemeris.state_gcrs(_times([0.0, inside]))
        message = str(error.value)
        assert message.startswith("gap.oem: ")
        assert f"falls in a 2400 s gap between the states of lines {before} and {after}" in message
        assert "\n" not in message
    # Next to the gap the windows stay on one side: the truth to 5 cm (across it: km).
    near = np.array([3540.0, 3570.0, 3599.0, 3600.0, 6000.0, 6001.0, 6030.0, 6090.0])
    r, v = ephemeris.state_gcrs(_times(near))
    r_true, v_true = _truth(near)
    assert np.linalg.norm(r - r_true, axis=1).max() < FIVE_CM
    assert np.linalg.norm(v - v_true, axis=1).max() < 1e-3


def test_smooth_step_changes_and_a_missing_state_are_not_gaps(caplog) -> None:
    dense = np.arange(0.0, 1800.0, 60.0)
    sparse = np.arange(1800.0, 1800.0 + 30 * 300.0, 300.0)  # the producer's coarser step
    missing_one = np.delete(dense, 10)  # one 120 s step among 60 s ones
    with caplog.at_level(logging.WARNING, logger="satsight.ephemeris.oem_segments"):
        for seconds in (np.concatenate([dense, sparse]), missing_one):
            ephemeris = parse_oem(_oem(seconds))
            ephemeris.state_gcrs(_times(np.linspace(seconds[0], seconds[-1], 301)))
    assert "gap" not in caplog.text


def test_gap_threshold_is_three_typical_steps() -> None:
    base = np.arange(0.0, 1200.0 + 1.0, 60.0)
    at_limit = np.concatenate([base, base[-1] + GAP_FACTOR * 60.0 + np.arange(0.0, 1201.0, 60.0)])
    parse_oem(_oem(at_limit)).state_gcrs(_times([base[-1] + 90.0]))  # 3 steps: kept
    beyond = np.concatenate([base, base[-1] + 190.0 + np.arange(0.0, 1201.0, 60.0)])
    with pytest.raises(SatsightError, match=r"falls in a 190 s gap"):
        parse_oem(_oem(beyond)).state_gcrs(_times([base[-1] + 90.0]))


def test_cli_frames_across_a_gap_are_refused_frames_beside_it_planned(tmp_path: Path) -> None:
    lines = [x for x in _iss_lines() if not ("2019-12-09T17:10" <= x[:16] <= "2019-12-09T17:49")]
    (tmp_path / "gap.oem").write_text("\n".join(lines) + "\n", encoding="utf-8")
    beside = _plan(tmp_path, _scenario(tmp_path, "gap.oem", duration_s=1500.0))
    assert beside.returncode == 0, beside.stderr
    assert "1 gap(s)" in beside.stderr
    planned = (tmp_path / "plan" / "plan.csv").read_bytes()
    for _ in range(2):
        across = _plan(tmp_path, _scenario(tmp_path, "gap.oem", duration_s=3600.0))
        _assert_refused(across, "gap.oem: 2019-12-09T17:", "gap between the states of lines")
        assert (tmp_path / "plan" / "plan.csv").read_bytes() == planned


# --- 3. impossible dates ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "field", "fragment"),
    [
        ("CREATION_DATE = 2025-06-21", "CREATION_DATE = 2025-02-29", "CREATION_DATE", "28 days"),
        ("START_TIME = 2025-06-21", "START_TIME = 2025-06-31", "START_TIME", "30 days"),
        ("STOP_TIME = 2025-06-21", "STOP_TIME = 2025-13-21", "STOP_TIME", "month 13"),
        ("OBJECT_ID = 2025-001A", "OBJECT_ID = 2025-001A\nREF_FRAME_EPOCH = 2025-04-31T00:00:00",
         "REF_FRAME_EPOCH", "30 days"),
        ("START_TIME = 2025-06-21T06:00:00.000000",
         "START_TIME = 2025-06-21T06:00:00.000000\nUSEABLE_START_TIME = 2025-366T00:00:00",
         "USEABLE_START_TIME", "2025 has 365 days"),
        ("2025-06-21T06:02:00.000000 ", "2025-06-00T06:02:00.000000 ", "epoch", "day 0"),
        ("2025-06-21T06:03:00.000000 ", "2025-06-21T24:03:00.000000 ", "epoch", "time of day"),
    ],
)  # fmt: skip
def test_oem_impossible_dates_name_the_line(old: str, new: str, field: str, fragment: str) -> None:
    text = _oem(np.arange(0.0, 600.0 + 1.0, 60.0))
    assert old in text
    edited = text.replace(old, new, 1)
    line = _line_of(edited, new.splitlines()[-1][:20])
    with pytest.raises(SatsightError) as error:
        parse_oem(edited, source="dates.oem")
    message = str(error.value)
    assert message.startswith(f"dates.oem, line {line}: {field} ")
    assert fragment in message


def test_oem_leap_day_and_day_366_of_a_leap_year_are_accepted() -> None:
    seconds = np.arange(0.0, 600.0 + 1.0, 60.0)
    r, v = _truth(seconds)
    times = timescale().utc(2024, 12, 31, 23, 55, seconds)  # into 2025
    text = format_oem(times, r, v, object_name="T", object_id="2024-001A")
    doy = text.replace("2024-12-31T", "2024-366T")
    assert parse_oem(doy).useable_start_utc == "2024-12-31T23:55:00.000000Z"
    leap = text.replace("CREATION_DATE = 2024-12-31", "CREATION_DATE = 2024-02-29")
    parse_oem(leap)


def test_cli_oem_with_an_impossible_date(tmp_path: Path) -> None:
    lines = [
        "START_TIME = 2019-11-31T16:00:00.000000" if x.startswith("START_TIME") else x
        for x in _iss_lines()
    ]
    (tmp_path / "bad.oem").write_text("\n".join(lines) + "\n", encoding="utf-8")
    line = next(i for i, x in enumerate(lines, 1) if x.startswith("START_TIME"))
    # In a child process, as typed at the command line: the other cases run in-process.
    result = _plan(tmp_path, _scenario(tmp_path, "bad.oem"), run=run_satsight)
    _assert_refused(result, f"bad.oem, line {line}: START_TIME '2019-11-31T16:00:00.000000'")
    assert not (tmp_path / "plan" / "plan.csv").exists()


def _kvn(fields: dict[str, str]) -> str:
    head = ["CCSDS_OMM_VERS = 2.0", "CREATION_DATE = 2019-12-10T00:00:00", "ORIGINATOR = TEST"]
    return "\n".join(head + [f"{k} = {v}" for k, v in fields.items()]) + "\n"


@pytest.mark.parametrize(
    ("epoch", "fragment"),
    [
        ("2019-11-31T16:38:29.363423", "2019-11 has 30 days, so day 31 does not exist"),
        ("2019-02-29T00:00:00", "2019-02 has 28 days"),
        ("2019-366T00:00:00", "day of year 366 does not exist (2019 has 365 days)"),
        ("2019-12-09T24:00:00", "time of day out of range"),
        ("2019-12-09T16:60:00", "time of day out of range"),
    ],
)
def test_omm_impossible_epoch_names_the_line_or_record(epoch: str, fragment: str) -> None:
    fields = {**ISS_OMM, "EPOCH": epoch}
    text = _kvn(fields)
    line = _line_of(text, "EPOCH")
    with pytest.raises(SatsightError, match=rf"^x.omm \(record 1\), line {line}: EPOCH ") as e:
        parse_omm(text, source="x.omm")
    assert fragment in str(e.value)
    with pytest.raises(SatsightError, match=r"^x.json \(record 2\): EPOCH ") as e:
        parse_omm(json.dumps([ISS_OMM, fields]), source="x.json")
    assert fragment in str(e.value)


def test_omm_leap_epochs_are_accepted() -> None:
    for epoch in ("2020-02-29T12:00:00", "2020-366T12:00:00"):
        orbit = parse_omm(json.dumps({**ISS_OMM, "EPOCH": epoch}))[0]
        assert orbit.epoch_utc.startswith(("2020-02-29T12:00:00", "2020-12-31T12:00:00"))


def _with_checksum(line: str) -> str:
    return line[:68] + str(tle_checksum(line))


@pytest.mark.parametrize(
    ("day", "fragment"),
    [("366.50000000", "day 366.5 does not exist in 2019"), ("000.50000000", "day 0.5")],
)
def test_tle_epoch_day_that_does_not_exist(day: str, fragment: str) -> None:
    line1 = _with_checksum(ISS_1[:20] + day + ISS_1[32:])
    with pytest.raises(SatsightError) as error:
        parse_tle(["ISS", line1, ISS_2], source="x.tle")
    assert str(error.value).startswith("x.tle, line 2: TLE line 1, columns 21-32 (epoch day")
    assert fragment in str(error.value)
    leap = _with_checksum(ISS_1[:18] + "20366.50000000" + ISS_1[32:])  # 2020 has 366 days
    assert parse_tle([leap, ISS_2])[0].epoch_utc.startswith("2020-12-31T12:00:00")


# --- 4. OMM numbers that SGP4 cannot take ----------------------------------------------------


@pytest.mark.parametrize(
    ("key", "value", "fragment"),
    [
        ("NORAD_CAT_ID", "1e20", "an integer 0-339999"),
        ("NORAD_CAT_ID", "340000", "an integer 0-339999"),
        ("NORAD_CAT_ID", "-1", "an integer 0-339999"),
        ("NORAD_CAT_ID", "25544.5", "an integer 0-339999"),
        ("ECCENTRICITY", "1.0", "0 <= e < 1"),
        ("ECCENTRICITY", "-0.1", "0 <= e < 1"),
        ("MEAN_MOTION", "0", "> 0 rev/day"),
        ("MEAN_MOTION", "-15.5", "> 0 rev/day"),
        ("INCLINATION", "181", "0-180 deg"),
        ("BSTAR", "nan", "must be a finite number"),
        ("MEAN_ANOMALY", "inf", "must be a finite number"),
        ("MEAN_MOTION_DOT", "1e400", "must be a finite number"),
    ],
)
def test_omm_values_out_of_sgp4_range(key: str, value: str, fragment: str) -> None:
    text = _kvn({**ISS_OMM, key: value})
    line = _line_of(text, key + " ")
    with pytest.raises(SatsightError) as error:
        parse_omm(text, source="x.omm")
    message = str(error.value)
    assert message.startswith(f"x.omm (record 1), line {line}: {key} = '{value}'")
    assert fragment in message


def test_omm_range_edges_are_accepted() -> None:
    orbit = parse_omm(json.dumps({**ISS_OMM, "NORAD_CAT_ID": "339999", "INCLINATION": "180"}))[0]
    assert orbit.catalog_number == "339999"
    assert select_orbit([orbit], 339999, "x.json") is orbit
    parse_omm(json.dumps({**ISS_OMM, "ECCENTRICITY": "0"}))


def test_cli_omm_catalogue_number_too_large(tmp_path: Path) -> None:
    (tmp_path / "big.omm").write_text(_kvn({**ISS_OMM, "NORAD_CAT_ID": "1e20"}), encoding="utf-8")
    scenario = (
        _scenario(tmp_path, "x").read_text().replace("oem:\n  file: x", "omm:\n  file: big.omm")
    )
    (tmp_path / "scenario.yaml").write_text(scenario, encoding="utf-8")
    result = _plan(tmp_path, tmp_path / "scenario.yaml")
    _assert_refused(result, "NORAD_CAT_ID = '1e20' is out of range; SGP4 needs an integer 0-339999")
    assert "OverflowError" not in result.stderr


# --- 5. state lines with and without accelerations -------------------------------------------


def test_mixed_six_and_nine_value_lines_name_the_line() -> None:
    text = _oem(np.arange(0.0, 600.0 + 1.0, 60.0))
    first = _line_of(text, "2025-06-21T06:00:00")
    odd = _line_of(text, "2025-06-21T06:05:00")
    lines = text.splitlines()
    lines[odd - 1] += " 0.001 0.002 0.003"
    with pytest.raises(SatsightError) as error:
        parse_oem("\n".join(lines), source="acc.oem")
    assert str(error.value) == (
        f"acc.oem, line {odd}: this state line holds 9 values but the segment's first state "
        f"line (line {first}) holds 6; within a segment every state line gives 6 values "
        "(position, velocity) or every one 9 (with accelerations)"
    )
    # Every line with accelerations: accepted, accelerations kept in m/s^2.
    state_lines = range(first - 1, first - 1 + 11)
    every = [x + " 0.001 0.002 0.003" if i in state_lines else x for i, x in enumerate(lines)]
    every[odd - 1] = lines[odd - 1]
    segment = parse_oem("\n".join(every)).segments[0]
    assert segment.a_m_s2 is not None and np.allclose(segment.a_m_s2[0], [1.0, 2.0, 3.0])


def test_cli_mixed_state_lines(tmp_path: Path) -> None:
    lines = _iss_lines()
    k = next(i for i, x in enumerate(lines) if x.startswith("2019-12-09T16:45"))
    lines[k] += " 0.001 0.002 0.003"
    (tmp_path / "acc.oem").write_text("\n".join(lines) + "\n", encoding="utf-8")
    result = _plan(tmp_path, _scenario(tmp_path, "acc.oem"))
    _assert_refused(result, f"acc.oem, line {k + 1}: this state line holds 9 values")
    assert "inhomogeneous" not in result.stdout + result.stderr
