"""CCSDS Orbit Ephemeris Messages (OEM, CCSDS 502.0-B), KVN form: read, interpolate, write.

An OEM is a table of states (epoch, position in km, velocity in km/s, optionally
acceleration in km/s^2) in one or more segments, each with a metadata block:

* ``CENTER_NAME`` must be ``EARTH``.
* ``REF_FRAME``: ``GCRF`` (and ``ICRF``, whose axes GCRS shares) are taken as GCRS;
  ``EME2000`` (also written ``J2000``) is turned into GCRS with the IERS frame bias
  (:func:`satsight.ephemeris.sun_moon.gcrs_from_eme2000`, about 23 mas). Other frames
  (TEME, ITRF, ...) are refused: they need Earth orientation data this reader does not take.
* ``TIME_SYSTEM``: ``UTC``, ``TAI``, ``TT``, ``GPS`` (TAI - 19 s) or ``TDB``, read with
  skyfield's timescale. Epochs are ``YYYY-MM-DDThh:mm:ss[.fff]`` or ``YYYY-DDDThh:mm:ss``.
* ``INTERPOLATION``: ``LAGRANGE`` (default) or ``HERMITE`` (``LINEAR`` is Lagrange of
  degree 1), of polynomial degree ``INTERPOLATION_DEGREE`` (default 7). Lagrange fits
  positions and velocities separately with the degree + 1 states nearest the time (centred,
  shifted inside at the segment's ends). Hermite fits positions with their velocities as
  derivatives on ceil((degree + 1) / 2) states, a polynomial of degree 2 n - 1 >= degree;
  the velocity is its derivative. Some tools read the degree as "number of states - 1"
  for Hermite as well; with states every few tens of seconds both are far below a metre.
* ``USEABLE_START_TIME`` / ``USEABLE_STOP_TIME`` (default the segment's ``START_TIME`` /
  ``STOP_TIME``) bound where a segment is used, and so do its first and last states: a
  time is never extrapolated, even where ``START_TIME`` precedes the first state (such a
  file is logged as a warning). A time outside every segment is refused with the spans
  that are held. Where segments overlap, the first one listed that holds the time is used.
* Gaps: a step between two states longer than ``GAP_FACTOR`` (3) times the typical step
  on both sides of it (the median of up to ``GAP_NEIGHBOURS`` (8) steps before it, and of
  up to 8 after it) is a gap. The truncation error of a degree-n polynomial grows as
  h^(n+1) with the node spacing h, so a window stretched over a gap of k steps can be
  k^(n+1) times less accurate than the file's own step was chosen to be (3^8 = 6561 at
  degree 7: a 40-minute hole in 60 s LEO states is kilometres). Interpolation windows
  never reach across a gap (they are shifted to one side, as at a segment's end), and a
  time inside a gap is refused with the gap's lines; gaps are logged when the file is read.

Covariance blocks (``COVARIANCE_START`` ... ``COVARIANCE_STOP``) and ``COMMENT`` lines are
skipped. The parser is strict: an unknown keyword, a data line with a wrong number of
values (or 9 values among lines of 6), an impossible date in any epoch field
(``CREATION_DATE``, the metadata times, each state), or epochs that do not increase are
errors naming the line.

Internally epochs are elapsed seconds (TT) from the message's first epoch, kept as a whole
TT Julian day plus a fraction so that sub-microsecond resolution survives.
"""

from __future__ import annotations

import calendar
import logging
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skyfield.timelib import Time

from satsight.ephemeris.sun_moon import gcrs_from_eme2000
from satsight.ephemeris.time import SECONDS_PER_DAY, format_epoch_utc, timescale
from satsight.errors import SatsightError

log = logging.getLogger(__name__)

DEFAULT_INTERPOLATION = "LAGRANGE"
DEFAULT_DEGREE = 7
MAX_FILE_BYTES = 200_000_000
# A step longer than GAP_FACTOR times the typical step on both sides of it (the median of
# up to GAP_NEIGHBOURS steps on that side) is a gap that interpolation must not cross.
GAP_FACTOR = 3.0
GAP_NEIGHBOURS = 8

_HEADER_KEYS = ("CCSDS_OEM_VERS", "CREATION_DATE", "ORIGINATOR", "MESSAGE_ID")
_META_KEYS = (
    "OBJECT_NAME",
    "OBJECT_ID",
    "CENTER_NAME",
    "REF_FRAME",
    "REF_FRAME_EPOCH",
    "TIME_SYSTEM",
    "START_TIME",
    "USEABLE_START_TIME",
    "USEABLE_STOP_TIME",
    "STOP_TIME",
    "INTERPOLATION",
    "INTERPOLATION_DEGREE",
)
_META_REQUIRED = (
    "OBJECT_NAME",
    "OBJECT_ID",
    "CENTER_NAME",
    "REF_FRAME",
    "TIME_SYSTEM",
    "START_TIME",
    "STOP_TIME",
)
_GCRS_FRAMES = ("GCRF", "ICRF")
_EME2000_FRAMES = ("EME2000", "J2000")
_TIME_SYSTEMS = ("UTC", "TAI", "TT", "GPS", "TDB")
_KVN_RE = re.compile(r"^([A-Z0-9_]+)\s*=\s*(.*?)\s*$")
_EPOCH_RE = re.compile(
    r"^(?P<year>\d{4})-(?:(?P<month>\d{2})-(?P<day>\d{2})|(?P<doy>\d{3}))"
    r"T(?P<hour>\d{2}):(?P<minute>\d{2}):(?P<second>\d{2}(?:\.\d*)?)Z?$"
)


def _error(source: str, line_no: int | None, message: str) -> SatsightError:
    where = f"{source}, line {line_no}" if line_no is not None else source
    return SatsightError(f"{where}: {message}")


def _times(time_system: str, fields: list[tuple[int, int, int, int, int, float]]) -> Time:
    """A vector skyfield Time from (year, month, day, hour, minute, second) rows."""
    y, mo, d, h, mi, s = (np.array(c) for c in zip(*fields, strict=True))
    ts = timescale()
    if time_system == "UTC":
        return ts.utc(y, mo, d, h, mi, s)
    if time_system == "TAI":
        return ts.tai(y, mo, d, h, mi, s)
    if time_system == "GPS":
        return ts.tai(y, mo, d, h, mi, s + 19.0)
    if time_system == "TT":
        return ts.tt(y, mo, d, h, mi, s)
    return ts.tdb(y, mo, d, h, mi, s)


def _epoch_fields(
    text: str, source: str, line_no: int, keyword: str = "epoch"
) -> tuple[int, int, int, int, int, float]:
    """(year, month, day, hour, minute, second) of an OEM epoch, checked against the
    calendar (month lengths, leap years); ``keyword`` names the field in messages."""
    m = _EPOCH_RE.match(text)
    if m is None:
        raise _error(
            source,
            line_no,
            f"{keyword} {text!r} is not YYYY-MM-DDThh:mm:ss[.fff] or YYYY-DDDThh:mm:ss[.fff]",
        )
    year = int(m["year"])
    if m["doy"] is not None:
        month, day = 1, int(m["doy"])  # skyfield carries day-of-year past January
        days_in_year = 366 if calendar.isleap(year) else 365
        if not 1 <= day <= days_in_year:
            raise _error(
                source,
                line_no,
                f"{keyword} {text!r}: day of year {day} does not exist ({year} has "
                f"{days_in_year} days); correct the date",
            )
    else:
        month, day = int(m["month"]), int(m["day"])
        if not 1 <= month <= 12:
            raise _error(source, line_no, f"{keyword} {text!r}: month {month} does not exist")
        days_in_month = calendar.monthrange(year, month)[1] if year >= 1 else 31
        if not 1 <= day <= days_in_month:
            raise _error(
                source,
                line_no,
                f"{keyword} {text!r}: {year:04d}-{month:02d} has {days_in_month} days, so day "
                f"{day} does not exist; correct the date",
            )
    hour, minute, second = int(m["hour"]), int(m["minute"]), float(m["second"])
    if hour > 23 or minute > 59 or second >= 61.0:
        raise _error(source, line_no, f"{keyword} {text!r}: time of day out of range")
    return year, month, day, hour, minute, second


def _gaps(t_s: np.ndarray) -> np.ndarray:
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
    t_s[i] -> t_s[i + 1] that are gaps (module docstring), which interpolation never crosses.
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


def parse_oem(text: str, source: str = "OEM") -> OemEphemeris:
    """Read the KVN text of an OEM (see the module docstring for what is accepted)."""
    lines = text.splitlines()
    header: dict[str, str] = {}
    keyword_lines: dict[str, int] = {}  # the line of each keyword of the current block
    header_lines: dict[str, int] = keyword_lines
    raw_segments: list[_RawSegment] = []
    state = "header"
    meta: dict[str, str] = {}
    data: list[tuple[int, list[str]]] = []
    meta_line = 0
    for no, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("COMMENT"):
            continue
        if state == "covariance":
            if line == "COVARIANCE_STOP":
                state = "data"
            continue
        if line == "META_START":
            if state not in ("header", "data"):
                raise _error(source, no, "META_START inside a metadata block")
            if state == "header":
                if "CCSDS_OEM_VERS" not in header:
                    raise _error(source, no, "the header must start with CCSDS_OEM_VERS")
            else:
                raw_segments.append((meta, data, meta_line, keyword_lines))
            meta, data, meta_line, state = {}, [], no, "meta"
            keyword_lines = {}
            continue
        if line == "META_STOP":
            if state != "meta":
                raise _error(source, no, "META_STOP without META_START")
            missing = [k for k in _META_REQUIRED if k not in meta]
            if missing:
                raise _error(source, no, f"metadata lacks {', '.join(missing)}")
            state = "data"
            continue
        if line == "COVARIANCE_START":
            if state != "data":
                raise _error(source, no, "COVARIANCE_START outside a data block")
            state = "covariance"
            continue
        if state in ("header", "meta"):
            m = _KVN_RE.match(line)
            if m is None:
                raise _error(source, no, f"expected 'KEYWORD = value'; got {raw!r}")
            key, value = m.group(1), m.group(2)
            allowed = _HEADER_KEYS if state == "header" else _META_KEYS
            if key not in allowed:
                block = "header" if state == "header" else "metadata"
                raise _error(source, no, f"unknown {block} keyword {key!r}")
            target = header if state == "header" else meta
            if key in target:
                raise _error(source, no, f"{key} given twice")
            if state == "header" and not header and key != "CCSDS_OEM_VERS":
                raise _error(source, no, "the header must start with CCSDS_OEM_VERS")
            target[key] = value
            keyword_lines[key] = no
            continue
        # A data line: epoch x y z vx vy vz [ax ay az].
        parts = line.split()
        if len(parts) not in (7, 10):
            raise _error(
                source,
                no,
                f"a state line holds an epoch and 6 values (or 9 with accelerations); "
                f"got {len(parts) - 1} values: {raw!r}",
            )
        data.append((no, parts))
    if state == "header":
        raise _error(source, None, "no segment (META_START ... META_STOP and states) found")
    if state == "meta":
        raise _error(source, None, "the last metadata block has no META_STOP")
    if state == "covariance":
        raise _error(source, None, "a covariance block has no COVARIANCE_STOP")
    raw_segments.append((meta, data, meta_line, keyword_lines))
    if "CREATION_DATE" in header:
        _epoch_fields(
            header["CREATION_DATE"], source, header_lines["CREATION_DATE"], "CREATION_DATE"
        )
    return _build(header, raw_segments, source)


# One segment as read: metadata, (line, fields) of its states, the META_START line, and
# the line of each metadata keyword.
_RawSegment = tuple[dict[str, str], list[tuple[int, list[str]]], int, dict[str, int]]


def _check_value_counts(data: list[tuple[int, list[str]]], source: str) -> None:
    """Every state line of a segment holds the same number of values (6, or 9 with
    accelerations); else an error naming the first line that differs."""
    first_no, first = data[0]
    for no, parts in data:
        if len(parts) != len(first):
            raise _error(
                source,
                no,
                f"this state line holds {len(parts) - 1} values but the segment's first state "
                f"line (line {first_no}) holds {len(first) - 1}; within a segment every state "
                "line gives 6 values (position, velocity) or every one 9 (with accelerations)",
            )


def _build(header: dict[str, str], raw_segments: list[_RawSegment], source: str) -> OemEphemeris:
    built = []
    reference: Time | None = None
    for meta, data, meta_line, keyword_lines in raw_segments:
        if meta["CENTER_NAME"].upper() != "EARTH":
            raise _error(
                source, meta_line, f"CENTER_NAME {meta['CENTER_NAME']!r}; only EARTH is accepted"
            )
        frame = meta["REF_FRAME"].upper()
        if frame not in _GCRS_FRAMES + _EME2000_FRAMES:
            raise _error(
                source,
                meta_line,
                f"REF_FRAME {meta['REF_FRAME']!r} is not supported; use GCRF, ICRF or EME2000",
            )
        time_system = meta["TIME_SYSTEM"].upper()
        if time_system not in _TIME_SYSTEMS:
            raise _error(
                source,
                meta_line,
                f"TIME_SYSTEM {meta['TIME_SYSTEM']!r} is not supported; use "
                f"{', '.join(_TIME_SYSTEMS)}",
            )
        interpolation = meta.get("INTERPOLATION", DEFAULT_INTERPOLATION).upper()
        if interpolation not in ("LAGRANGE", "HERMITE", "LINEAR"):
            raise _error(
                source,
                meta_line,
                f"INTERPOLATION {meta['INTERPOLATION']!r}; use LAGRANGE, HERMITE or LINEAR",
            )
        try:
            degree = int(meta.get("INTERPOLATION_DEGREE", 1 if interpolation == "LINEAR" else 7))
        except ValueError:
            raise _error(
                source, meta_line, f"INTERPOLATION_DEGREE {meta['INTERPOLATION_DEGREE']!r}"
            ) from None
        if not 1 <= degree <= 32:
            raise _error(source, meta_line, f"INTERPOLATION_DEGREE {degree} outside 1-32")
        if interpolation == "LINEAR":
            interpolation, degree = "LAGRANGE", 1
        if len(data) < 2:
            raise _error(source, meta_line, f"a segment needs at least 2 states; got {len(data)}")
        bounds = {
            key: meta.get(key)
            for key in ("START_TIME", "STOP_TIME", "USEABLE_START_TIME", "USEABLE_STOP_TIME")
        }
        bounds["USEABLE_START_TIME"] = bounds["USEABLE_START_TIME"] or bounds["START_TIME"]
        bounds["USEABLE_STOP_TIME"] = bounds["USEABLE_STOP_TIME"] or bounds["STOP_TIME"]
        if "REF_FRAME_EPOCH" in meta:
            _epoch_fields(
                meta["REF_FRAME_EPOCH"], source, keyword_lines["REF_FRAME_EPOCH"], "REF_FRAME_EPOCH"
            )
        # START_TIME and STOP_TIME come first: a default USEABLE_* is checked as them.
        fields = [
            _epoch_fields(bounds[k], source, keyword_lines.get(k, meta_line), k) for k in bounds
        ]
        fields += [_epoch_fields(parts[0], source, no) for no, parts in data]
        times = _times(time_system, fields)
        if reference is None:
            reference = timescale().tt_jd(float(times.whole[4]), float(times.tt_fraction[4]))
        whole = np.asarray(times.whole) - float(reference.whole)
        seconds = (whole + np.asarray(times.tt_fraction) - float(reference.tt_fraction)) * (
            SECONDS_PER_DAY
        )
        start, stop, ustart, ustop = (float(x) for x in seconds[:4])
        t_s = seconds[4:]
        bad = np.flatnonzero(np.diff(t_s) <= 0)
        if bad.size:
            raise _error(source, data[int(bad[0]) + 1][0], "epochs must increase strictly")
        _check_value_counts(data, source)
        try:
            values = np.array([[float(x) for x in parts[1:]] for _, parts in data])
        except ValueError:
            for no, parts in data:
                for x in parts[1:]:
                    try:
                        float(x)
                    except ValueError:
                        raise _error(source, no, f"{x!r} is not a number") from None
            raise
        if not np.all(np.isfinite(values)):
            row = int(np.flatnonzero(~np.all(np.isfinite(values), axis=1))[0])
            raise _error(source, data[row][0], "a state holds a non-finite value")
        if start > stop or not start <= ustart <= ustop <= stop:
            raise _error(
                source,
                meta_line,
                "need START_TIME <= USEABLE_START_TIME <= USEABLE_STOP_TIME <= STOP_TIME",
            )
        tolerance = 1e-6
        if t_s[0] < start - tolerance or t_s[-1] > stop + tolerance:
            raise _error(source, meta_line, "states lie outside START_TIME - STOP_TIME")
        lines = np.array([no for no, _ in data], dtype=np.int64)
        _check_held_span(source, meta, keyword_lines, meta_line, t_s, lines, ustart, ustop)
        gaps = _gaps(t_s)
        if gaps.size:
            longest = int(gaps[np.argmax(np.diff(t_s)[gaps])])
            log.warning(
                "%s: %d gap(s) in the states of the segment at line %d (longest %g s, between "
                "lines %d and %d), each more than %g times the typical step around it; times "
                "inside a gap are refused",
                source,
                gaps.size,
                meta_line,
                float(t_s[longest + 1] - t_s[longest]),
                int(lines[longest]),
                int(lines[longest + 1]),
                GAP_FACTOR,
            )
        r = values[:, 0:3] * 1e3
        v = values[:, 3:6] * 1e3
        a = values[:, 6:9] * 1e3 if values.shape[1] == 9 else None
        if frame in _EME2000_FRAMES:
            r, v = gcrs_from_eme2000(r), gcrs_from_eme2000(v)
            a = None if a is None else gcrs_from_eme2000(a)
        needed = degree + 1 if interpolation == "LAGRANGE" else math.ceil((degree + 1) / 2)
        if len(t_s) < needed:
            log.warning(
                "%s: a segment has %d states, fewer than the %d that %s of degree %d needs; "
                "using all of them",
                source,
                len(t_s),
                needed,
                interpolation.lower(),
                degree,
            )
        built.append(
            OemSegment(
                metadata=dict(meta),
                t_s=t_s,
                r_m=r,
                v_m_s=v,
                a_m_s2=a,
                start_s=start,
                stop_s=stop,
                useable_start_s=ustart,
                useable_stop_s=ustop,
                interpolation=interpolation,
                degree=degree,
                line_numbers=lines,
                gap_after=gaps,
            )
        )
    return OemEphemeris(
        header=dict(header), segments=tuple(built), reference=reference, source=source
    )


def _check_held_span(
    source: str,
    meta: dict[str, str],
    keyword_lines: dict[str, int],
    meta_line: int,
    t_s: np.ndarray,
    lines: np.ndarray,
    ustart: float,
    ustop: float,
) -> None:
    """Refuse a segment whose useable span holds none of its states' span; log one whose
    useable span reaches beyond its first or last state (those times are refused, never
    extrapolated)."""
    tolerance = 1e-6
    start_key = "USEABLE_START_TIME" if "USEABLE_START_TIME" in meta else "START_TIME"
    stop_key = "USEABLE_STOP_TIME" if "USEABLE_STOP_TIME" in meta else "STOP_TIME"
    if max(ustart, t_s[0]) > min(ustop, t_s[-1]):
        raise _error(
            source,
            keyword_lines.get(start_key, meta_line),
            f"{start_key} - {stop_key} ({meta[start_key]} to {meta[stop_key]}) holds none of "
            f"the segment's states (lines {int(lines[0])} to {int(lines[-1])}); correct the "
            "times or the states",
        )
    if ustart < t_s[0] - tolerance:
        log.warning(
            "%s, line %d: %s %s precedes the segment's first state (line %d, %g s later); "
            "times before that state are refused, and a scenario without epoch_utc starts there",
            source,
            keyword_lines.get(start_key, meta_line),
            start_key,
            meta[start_key],
            int(lines[0]),
            float(t_s[0] - ustart),
        )
    if ustop > t_s[-1] + tolerance:
        log.warning(
            "%s, line %d: %s %s follows the segment's last state (line %d, %g s earlier); "
            "times after that state are refused",
            source,
            keyword_lines.get(stop_key, meta_line),
            stop_key,
            meta[stop_key],
            int(lines[-1]),
            float(ustop - t_s[-1]),
        )


def read_oem(path: str | Path) -> OemEphemeris:
    """Read the OEM (KVN) file ``path``."""
    path = Path(path)
    if not path.is_file():
        raise SatsightError(f"OEM file not found: {path}")
    if path.stat().st_size > MAX_FILE_BYTES:
        raise SatsightError(f"{path}: larger than {MAX_FILE_BYTES} bytes; not an OEM file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise SatsightError(f"{path}: not UTF-8 text; expected an OEM (KVN) file") from None
    return parse_oem(text, source=str(path))


def format_oem(
    times: Time,
    r_gcrs_m: np.ndarray,
    v_gcrs_m_s: np.ndarray,
    *,
    object_name: str,
    object_id: str,
    originator: str = "satsight",
    interpolation: str = DEFAULT_INTERPOLATION,
    degree: int = DEFAULT_DEGREE,
    comments: tuple[str, ...] = (),
    creation_utc: str | None = None,
) -> str:
    """The KVN text of a one-segment OEM (REF_FRAME GCRF, TIME_SYSTEM UTC, CENTER EARTH)
    from GCRS states (N, 3) m and m/s at the (N,) skyfield ``times``.

    Epochs are written to 1 µs, positions to 1 mm and velocities to 1 µm/s."""
    r = np.asarray(r_gcrs_m, dtype=np.float64) / 1e3
    v = np.asarray(v_gcrs_m_s, dtype=np.float64) / 1e3
    epochs = [e.rstrip("Z") for e in format_epoch_utc(times, places=6)]
    creation = (creation_utc or epochs[0]).rstrip("Z")
    out = ["CCSDS_OEM_VERS = 2.0"]
    out += [f"COMMENT {c}" for c in comments]
    out += [f"CREATION_DATE = {creation}", f"ORIGINATOR = {originator}", "", "META_START"]
    out += [
        f"OBJECT_NAME = {object_name}",
        f"OBJECT_ID = {object_id}",
        "CENTER_NAME = EARTH",
        "REF_FRAME = GCRF",
        "TIME_SYSTEM = UTC",
        f"START_TIME = {epochs[0]}",
        f"STOP_TIME = {epochs[-1]}",
        f"INTERPOLATION = {interpolation}",
        f"INTERPOLATION_DEGREE = {degree}",
        "META_STOP",
        "",
    ]
    for epoch, ri, vi in zip(epochs, r, v, strict=True):
        out.append(
            f"{epoch} {ri[0]:.6f} {ri[1]:.6f} {ri[2]:.6f} {vi[0]:.9f} {vi[1]:.9f} {vi[2]:.9f}"
        )
    return "\n".join(out) + "\n"
