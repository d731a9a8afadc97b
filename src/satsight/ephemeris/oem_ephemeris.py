"""An OEM ephemeris in memory: its segments of GCRS states and their interpolation.

Each segment is interpolated as its metadata says (``LAGRANGE`` or ``HERMITE`` of a given
degree) from the states nearest the time, never across a gap between states and never
outside the span the segment holds; the format, the interpolation and the gap rule are
described in :mod:`satsight.ephemeris.oem`.

Epochs are elapsed seconds (TT) from the message's first epoch, kept as a whole TT Julian
day plus a fraction so that sub-microsecond resolution survives.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from skyfield.timelib import Time

from satsight.ephemeris.time import SECONDS_PER_DAY, format_epoch_utc, timescale
from satsight.errors import SatsightError

# A step longer than GAP_FACTOR times the typical step on both sides of it (the median of
# up to GAP_NEIGHBOURS steps on that side) is a gap that interpolation must not cross.
GAP_FACTOR = 3.0
GAP_NEIGHBOURS = 8


def find_gaps(t_s: np.ndarray) -> np.ndarray:
    """Indices i of the steps t_s[i] -> t_s[i + 1] that are gaps: longer than GAP_FACTOR
    times the typical step on both sides (the median of up to GAP_NEIGHBOURS steps before
    the step and of up to GAP_NEIGHBOURS after it; one side alone at a segment's end)."""
    steps = np.diff(t_s)
    if steps.size < 2:
        return np.zeros(0, dtype=np.int64)
    k = GAP_NEIGHBOURS
    padded = np.concatenate([np.full(k, np.nan), steps, np.full(k, np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * k + 1)  # centred on i
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN sides at the ends
        before = np.nanmedian(windows[:, :k], axis=1)
        after = np.nanmedian(windows[:, k + 1 :], axis=1)
    typical = np.fmax(before, after)  # NaN only where both sides are empty (never here)
    return np.flatnonzero(steps > GAP_FACTOR * typical)


@dataclass(frozen=True)
class OemSegment:
    """One segment: its metadata and its states, converted to GCRS and SI.

    t_s (N,): TT seconds after the message reference epoch; r_m (N, 3), v_m_s (N, 3): GCRS
    position and velocity; a_m_s2 (N, 3) or None: acceleration as given (GCRS axes).
    start_s, stop_s, useable_start_s, useable_stop_s: the segment's bounds, same scale.
    line_numbers (N,): the file line of each state; gap_after (G,): indices i of the steps
    t_s[i] -> t_s[i + 1] that are gaps (``find_gaps``), which interpolation never crosses.
    """

    metadata: dict[str, str]
    t_s: np.ndarray
    r_m: np.ndarray
    v_m_s: np.ndarray
    a_m_s2: np.ndarray | None
    start_s: float
    stop_s: float
    useable_start_s: float
    useable_stop_s: float
    interpolation: str
    degree: int
    line_numbers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    gap_after: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def held_start_s(self) -> float:
        """The first time the segment answers for: useable and not before its first state."""
        return max(self.useable_start_s, float(self.t_s[0]))

    @property
    def held_stop_s(self) -> float:
        """The last time the segment answers for: useable and not after its last state."""
        return min(self.useable_stop_s, float(self.t_s[-1]))

    def _pieces(self) -> list[tuple[int, int]]:
        """[first, last] state indices of the runs of states between gaps."""
        cuts = [int(i) for i in self.gap_after]
        firsts = [0, *(i + 1 for i in cuts)]
        lasts = [*cuts, len(self.t_s) - 1]
        return list(zip(firsts, lasts, strict=True))

    def in_gap(self, t_s: np.ndarray) -> np.ndarray:
        """(M,) index of the gap step holding each time strictly inside it, or -1."""
        where = np.full(len(t_s), -1, dtype=np.int64)
        for i in self.gap_after:
            inside = (t_s > self.t_s[i]) & (t_s < self.t_s[i + 1])
            where[inside] = i
        return where

    def holds(self, t_s: np.ndarray) -> np.ndarray:
        """(M,) whether the segment interpolates each time: inside its useable span, its
        states' span, and not inside a gap."""
        inside = (t_s >= self.held_start_s) & (t_s <= self.held_stop_s)
        return inside & (self.in_gap(t_s) < 0)

    def interpolate(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """GCRS position (M, 3), m, and velocity (M, 3), m/s, at t_s (M,) that the segment
        holds; each time uses only the states of its run between gaps."""
        r = np.full((len(t_s), 3), np.nan)
        v = np.full((len(t_s), 3), np.nan)
        left = np.ones(len(t_s), dtype=bool)
        for first, last in self._pieces():
            here = left & (t_s >= self.t_s[first]) & (t_s <= self.t_s[last])
            if not np.any(here):
                continue
            nodes = self.t_s[first : last + 1]
            rs, vs = self.r_m[first : last + 1], self.v_m_s[first : last + 1]
            if self.interpolation == "HERMITE":
                r[here], v[here] = _hermite(nodes, rs, vs, t_s[here], self.degree)
            else:
                r[here] = _lagrange(nodes, rs, t_s[here], self.degree)
                v[here] = _lagrange(nodes, vs, t_s[here], self.degree)
            left &= ~here
        return r, v


def _window(nodes: np.ndarray, t_s: np.ndarray, count: int) -> np.ndarray:
    """(M, count) indices of the ``count`` consecutive nodes centred on each time."""
    n = len(nodes)
    right = np.searchsorted(nodes, t_s, side="right")  # first node after t
    first = np.clip(right - count // 2, 0, n - count)
    return first[:, None] + np.arange(count)[None, :]


def _lagrange(nodes: np.ndarray, values: np.ndarray, t_s: np.ndarray, degree: int) -> np.ndarray:
    """Lagrange interpolation of ``values`` (N, 3) at ``t_s`` with degree + 1 centred nodes."""
    count = min(degree + 1, len(nodes))
    idx = _window(nodes, t_s, count)
    x = nodes[idx]  # (M, count)
    scale = max(float(np.ptp(nodes)), 1.0)
    x = (x - t_s[:, None]) / scale  # times relative to t: better conditioned
    out = np.zeros((len(t_s), values.shape[1]))
    for j in range(count):
        weight = np.ones(len(t_s))
        for k in range(count):
            if k != j:
                weight *= (0.0 - x[:, k]) / (x[:, j] - x[:, k])
        out += weight[:, None] * values[idx[:, j]]
    return out


def _hermite(
    nodes: np.ndarray, r: np.ndarray, v: np.ndarray, t_s: np.ndarray, degree: int
) -> tuple[np.ndarray, np.ndarray]:
    """Hermite interpolation of positions with velocities as derivatives (divided
    differences on doubled nodes); returns the position and its derivative at ``t_s``."""
    count = min(max(math.ceil((degree + 1) / 2), 1), len(nodes))
    idx = _window(nodes, t_s, count)
    m = len(t_s)
    z = np.repeat(nodes[idx] - t_s[:, None], 2, axis=1)  # (M, 2n), relative to t
    q = np.repeat(r[idx], 2, axis=1)  # (M, 2n, 3)
    dv = np.repeat(v[idx], 2, axis=1)
    size = 2 * count
    # Newton divided differences in place; column 1 uses the derivative on repeated nodes.
    coef = q.copy()
    for level in range(1, size):
        prev = coef.copy()
        for i in range(level, size):
            dz = z[:, i] - z[:, i - level]
            if level == 1 and i % 2 == 1:
                coef[:, i] = dv[:, i]
            else:
                coef[:, i] = (prev[:, i] - prev[:, i - 1]) / dz[:, None]
    # Evaluate the Newton form and its derivative at 0 (t itself) by Horner's scheme.
    pos = coef[:, size - 1].copy()
    vel = np.zeros((m, 3))
    for i in range(size - 2, -1, -1):
        factor = (0.0 - z[:, i])[:, None]
        vel = vel * factor + pos
        pos = pos * factor + coef[:, i]
    return pos, vel


@dataclass(frozen=True)
class OemEphemeris:
    """An OEM read into GCRS: header keywords, segments, and the reference epoch."""

    header: dict[str, str]
    segments: tuple[OemSegment, ...]
    reference: Time  # scalar: the first epoch of the message
    source: str

    @property
    def object_name(self) -> str:
        return self.segments[0].metadata["OBJECT_NAME"]

    def seconds_from_reference(self, times: Time) -> np.ndarray:
        """TT seconds from the reference epoch to ``times``, (N,)."""
        whole = np.atleast_1d(np.asarray(times.whole, dtype=np.float64))
        frac = np.atleast_1d(np.asarray(times.tt_fraction, dtype=np.float64))
        return (
            (whole - float(self.reference.whole)) + (frac - float(self.reference.tt_fraction))
        ) * (SECONDS_PER_DAY)

    def time_at(self, seconds: float) -> Time:
        """The scalar Time ``seconds`` (TT) after the reference epoch."""
        days = math.floor(seconds / SECONDS_PER_DAY)
        rest = (seconds - days * SECONDS_PER_DAY) / SECONDS_PER_DAY
        return timescale().tt_jd(
            float(self.reference.whole) + days, float(self.reference.tt_fraction) + rest
        )

    @property
    def useable_start(self) -> Time:
        """The first instant the message may be used: the earliest time a segment holds
        (inside its useable span and not before its first state)."""
        return self.time_at(min(s.held_start_s for s in self.segments))

    @property
    def useable_start_utc(self) -> str:
        return format_epoch_utc(self.useable_start, places=6)

    def state_gcrs(self, times: Time) -> tuple[np.ndarray, np.ndarray]:
        """GCRS position (N, 3), m, and velocity (N, 3), m/s, interpolated at ``times``.

        Raises SatsightError for a time outside every segment's useable span.
        """
        t = self.seconds_from_reference(times)
        r = np.full((len(t), 3), np.nan)
        v = np.full((len(t), 3), np.nan)
        left = np.ones(len(t), dtype=bool)
        for segment in self.segments:
            here = left & segment.holds(t)
            if np.any(here):
                r[here], v[here] = segment.interpolate(t[here])
                left &= ~here
        if np.any(left):
            i = int(np.flatnonzero(left)[0])
            when = format_epoch_utc(self.time_at(float(t[i])), 3)
            for segment in self.segments:
                gap = int(segment.in_gap(t[i : i + 1])[0])
                inside = segment.held_start_s <= t[i] <= segment.held_stop_s
                if gap >= 0 and inside:
                    raise SatsightError(self._gap_message(segment, gap, when))
            spans = "; ".join(
                f"{format_epoch_utc(self.time_at(s.held_start_s), 3)} to "
                f"{format_epoch_utc(self.time_at(s.held_stop_s), 3)}"
                for s in self.segments
            )
            raise SatsightError(
                f"{self.source}: {when} (UTC) lies outside the ephemeris's useable span(s) "
                f"{spans} (inside USEABLE_START_TIME - USEABLE_STOP_TIME and between the "
                "first and last states; never extrapolated); choose epoch_utc and the "
                "sampler's span inside them"
            )
        return r, v

    def _gap_message(self, segment: OemSegment, gap: int, when: str) -> str:
        t0, t1 = float(segment.t_s[gap]), float(segment.t_s[gap + 1])
        lines = segment.line_numbers
        return (
            f"{self.source}: {when} (UTC) falls in a {t1 - t0:g} s gap between the states of "
            f"lines {int(lines[gap])} and {int(lines[gap + 1])} "
            f"({format_epoch_utc(self.time_at(t0), 3)} to {format_epoch_utc(self.time_at(t1), 3)}"
            f"), more than {GAP_FACTOR:g} times the typical step around it; interpolating "
            "across it would be far less accurate than the file's own step (the error grows "
            "as the step to the power degree + 1); choose epoch_utc and the sampler's span "
            "outside the gap, or supply the missing states"
        )

    def first_state_gcrs(self) -> tuple[np.ndarray, np.ndarray]:
        """The first state of the first segment, GCRS m and m/s."""
        return self.segments[0].r_m[0].copy(), self.segments[0].v_m_s[0].copy()
