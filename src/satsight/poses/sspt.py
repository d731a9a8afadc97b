"""SSPT, "sequential frames along a predefined trajectory": frame times along a trajectory.

The sampler of the paper (*An Enhanced Method for Optical Imaging Computation of Space
Objects Integrating an Improved Phong Model and Higher-Order Spherical Harmonics*, Remote
Sensing, 2025), as pure sampling math: frame times at uniform intervals along a trajectory
segment (:func:`sspt_times_s`), or at uniform steps of the phase angle of a periodic motion
such as a fly-around (:func:`sspt_angle_times_s`); placing the camera at those times is done
elsewhere.

Units are SI (s) except where a name says otherwise (``_deg``).
"""

from __future__ import annotations

import math

import numpy as np

from satsight.errors import SatsightError
from satsight.poses.sampler_arguments import check_count, check_finite

SSPT_TIME_TOLERANCE_S = 1e-9
"""A time grid point within this many seconds of the segment end counts as the end."""

ANGLE_TOLERANCE_STEPS = 1e-9
"""An angle grid point within this fraction of a step of the stop angle counts as the stop."""


def sspt_times_s(
    start_s: float,
    end_s: float,
    frame_count: int | None = None,
    step_s: float | None = None,
    include_end: bool = True,
) -> np.ndarray:
    """Frame times (N,) in seconds along the trajectory segment from ``start_s`` to ``end_s``.

    Give exactly one of:

    frame_count: N frames evenly spaced. With ``include_end`` they run from start to end
    inclusive (``np.linspace``; N == 1 gives ``[start_s]``); without, they divide
    ``[start_s, end_s)`` into N equal steps (a closed orbit then has no repeated frame).
    step_s: one frame every ``step_s`` seconds, ``start_s + k step_s``, while the time does
    not pass ``end_s`` (a grid point within :data:`SSPT_TIME_TOLERANCE_S` of the end counts
    as the end). The end itself is a frame only when it lands on that grid and
    ``include_end`` is set.

    Times are on the caller's time axis (e.g. seconds from the scenario epoch).
    """
    start = check_finite(start_s, "segment start time (s)")
    end = check_finite(end_s, "segment end time (s)")
    if end < start:
        raise SatsightError(
            f"segment end must not precede its start, got start_s={start} s, end_s={end} s"
        )
    if (frame_count is None) == (step_s is None):
        raise SatsightError(
            "give exactly one of frame_count (N evenly spaced frames) or step_s (one frame "
            f"every step_s seconds); got frame_count={frame_count!r}, step_s={step_s!r}"
        )
    if frame_count is not None:
        n = check_count(frame_count, "frame_count", 1)
        if n > 1 and end == start:
            raise SatsightError(
                f"{n} frames on a segment of zero length would share one time ({start} s); "
                "give end_s > start_s or frame_count=1"
            )
        if include_end:
            return np.linspace(start, end, n)
        return start + (end - start) * (np.arange(n, dtype=np.float64) / n)
    step = check_finite(step_s, "step_s")
    if not step > 0:
        raise SatsightError(f"step_s must be positive, got {step} s")
    k_last = math.floor((end - start + SSPT_TIME_TOLERANCE_S) / step)
    times = start + step * np.arange(k_last + 1, dtype=np.float64)
    if not include_end:
        times = times[times < end - SSPT_TIME_TOLERANCE_S]
    if times.size == 0:
        raise SatsightError(
            f"no frame time lies in [{start}, {end}) s without the end; give end_s > "
            "start_s or include_end=True"
        )
    return times


def sspt_angle_times_s(
    period_s: float,
    start_deg: float,
    stop_deg: float,
    step_deg: float,
    start_s: float = 0.0,
    include_stop: bool = False,
) -> np.ndarray:
    """Frame times (N,) in seconds of a uniform periodic motion at evenly stepped angles.

    The motion (e.g. a fly-around) turns 360 deg every ``period_s`` seconds and is at phase
    angle 0 deg at time ``start_s``, so angle ``a`` is reached at
    ``start_s + period_s a / 360``. Frames sit at ``start_deg, start_deg + step_deg, ...``
    while below ``stop_deg``; with ``include_stop`` the stop angle is a frame too when it
    lands on that grid (within :data:`ANGLE_TOLERANCE_STEPS` of a step).

    Default ``include_stop=False``: the paper's "0 deg to 360 deg at 5 deg per frame" gives
    72 distinct views at ``k period_s / 72``, since 0 deg and 360 deg are the same view;
    ``include_stop=True`` gives 73 frames, the last repeating the first.
    """
    period = check_finite(period_s, "period_s")
    start = check_finite(start_deg, "start_deg")
    stop = check_finite(stop_deg, "stop_deg")
    step = check_finite(step_deg, "step_deg")
    t0 = check_finite(start_s, "start_s")
    if not period > 0:
        raise SatsightError(f"period_s must be positive, got {period} s")
    if not step > 0:
        raise SatsightError(f"step_deg must be positive, got {step} deg")
    if stop < start:
        raise SatsightError(
            f"stop angle must not precede the start angle, got start_deg={start}, "
            f"stop_deg={stop}; angles grow with time"
        )
    k = np.arange(math.floor((stop - start) / step + ANGLE_TOLERANCE_STEPS) + 1)
    angles_deg = start + step * k.astype(np.float64)
    if not include_stop:
        angles_deg = angles_deg[angles_deg < stop - ANGLE_TOLERANCE_STEPS * step]
    if angles_deg.size == 0:
        raise SatsightError(
            f"no angle lies in [{start}, {stop}) deg; give stop_deg > start_deg or "
            "include_stop=True"
        )
    return t0 + period * (angles_deg / 360.0)
