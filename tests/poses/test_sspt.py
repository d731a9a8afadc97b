"""SSPT frame times: evenly spaced along a segment, on a step grid, at stepped angles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.poses.sspt import sspt_angle_times_s, sspt_times_s

RTOL_TIME = 1e-12


# --------------------------------------------------------------------------- SSPT


def test_sspt_frame_count_spans_the_segment() -> None:
    t = sspt_times_s(100.0, 200.0, frame_count=11)
    np.testing.assert_allclose(t, 100.0 + 10.0 * np.arange(11), rtol=RTOL_TIME, atol=0)
    assert t[0] == 100.0 and t[-1] == 200.0
    open_end = sspt_times_s(100.0, 200.0, frame_count=10, include_end=False)
    np.testing.assert_allclose(open_end, 100.0 + 10.0 * np.arange(10), rtol=RTOL_TIME, atol=0)
    np.testing.assert_array_equal(sspt_times_s(5.0, 9.0, frame_count=1), [5.0])
    np.testing.assert_array_equal(sspt_times_s(5.0, 5.0, frame_count=1), [5.0])


@pytest.mark.parametrize(
    ("start_s", "end_s", "step_s", "include_end", "expected_count", "last_s"),
    [
        (0.0, 10.0, 2.0, True, 6, 10.0),
        (0.0, 10.0, 2.0, False, 5, 8.0),
        (0.0, 10.5, 2.0, True, 6, 10.0),  # end off the grid: never a frame
        (0.0, 10.5, 2.0, False, 6, 10.0),
        (0.0, 1.0, 0.1, True, 11, 1.0),  # 10 * 0.1 lands on 1.0 within 1e-9 s
        (3.0, 3.0, 1.0, True, 1, 3.0),
        (-5.0, 5.0, 2.5, True, 5, 5.0),
    ],
)
def test_sspt_step_grid(start_s, end_s, step_s, include_end, expected_count, last_s) -> None:
    t = sspt_times_s(start_s, end_s, step_s=step_s, include_end=include_end)
    assert t.shape == (expected_count,)
    assert t[0] == start_s
    np.testing.assert_allclose(t[-1], last_s, rtol=RTOL_TIME, atol=1e-12)
    if expected_count > 1:
        np.testing.assert_allclose(np.diff(t), step_s, rtol=RTOL_TIME, atol=0)


def test_sspt_one_frame_every_k_seconds_on_a_long_segment() -> None:
    t = sspt_times_s(0.0, 5400.0, step_s=30.0)
    assert t.shape == (181,)
    np.testing.assert_allclose(np.diff(t), 30.0, rtol=RTOL_TIME, atol=0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"start_s": 10.0, "end_s": 5.0, "frame_count": 3}, "precede"),
        ({"start_s": 0.0, "end_s": 5.0}, "exactly one"),
        ({"start_s": 0.0, "end_s": 5.0, "frame_count": 3, "step_s": 1.0}, "exactly one"),
        ({"start_s": 0.0, "end_s": 5.0, "step_s": 0.0}, "positive"),
        ({"start_s": 0.0, "end_s": 5.0, "step_s": -1.0}, "positive"),
        ({"start_s": 0.0, "end_s": 5.0, "frame_count": 0}, "frame_count"),
        ({"start_s": 0.0, "end_s": 5.0, "frame_count": 2.0}, "frame_count"),
        ({"start_s": 0.0, "end_s": 0.0, "frame_count": 3}, "zero length"),
        ({"start_s": 0.0, "end_s": 0.0, "step_s": 1.0, "include_end": False}, "no frame"),
        ({"start_s": math.nan, "end_s": 5.0, "frame_count": 3}, "finite"),
    ],
)
def test_sspt_times_errors(kwargs, match) -> None:
    with pytest.raises(SatsightError, match=match):
        sspt_times_s(**kwargs)


def test_sspt_fly_around_at_five_degrees() -> None:
    period_s = 5760.0
    t = sspt_angle_times_s(period_s, 0.0, 360.0, 5.0)
    assert t.shape == (72,)
    np.testing.assert_allclose(t, np.arange(72) * period_s / 72, rtol=RTOL_TIME, atol=0)
    with_stop = sspt_angle_times_s(period_s, 0.0, 360.0, 5.0, include_stop=True)
    assert with_stop.shape == (73,)
    assert with_stop[-1] == period_s


def test_sspt_angle_times_phase_and_offset() -> None:
    # Angle a is reached at start_s + period a / 360; start_s is the epoch of 0 deg.
    t = sspt_angle_times_s(360.0, 90.0, 180.0, 30.0, start_s=1000.0)
    np.testing.assert_allclose(t, [1090.0, 1120.0, 1150.0], rtol=RTOL_TIME, atol=0)
    t = sspt_angle_times_s(360.0, 0.0, 100.0, 30.0, include_stop=True)  # stop off the grid
    np.testing.assert_allclose(t, [0.0, 30.0, 60.0, 90.0], rtol=RTOL_TIME, atol=0)
    # 0.1 deg steps: the float grid lands on the stop within tolerance.
    t = sspt_angle_times_s(360.0, 0.0, 1.0, 0.1, include_stop=True)
    assert t.shape == (11,)


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        ((0.0, 0.0, 360.0, 5.0), {}, "period_s"),
        ((100.0, 0.0, 360.0, 0.0), {}, "step_deg"),
        ((100.0, 0.0, 360.0, -5.0), {}, "step_deg"),
        ((100.0, 90.0, 0.0, 5.0), {}, "precede"),
        ((100.0, 10.0, 10.0, 5.0), {}, "no angle"),
        ((100.0, 0.0, math.inf, 5.0), {}, "finite"),
    ],
)
def test_sspt_angle_times_errors(args, kwargs, match) -> None:
    with pytest.raises(SatsightError, match=match):
        sspt_angle_times_s(*args, **kwargs)
    assert sspt_angle_times_s(100.0, 10.0, 10.0, 5.0, include_stop=True).shape == (1,)
