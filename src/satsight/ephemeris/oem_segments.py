"""From an OEM's blocks as read (metadata keywords, state lines) to an ``OemEphemeris``.

Each segment's metadata is checked (centre, frame, time system, interpolation and its
degree, the START/STOP and USEABLE times), every epoch is read against the calendar in its
time system, the states are converted to GCRS (``EME2000`` through the IERS frame bias) and
SI, and gaps between states are found; errors name the line. What is accepted is described
in :mod:`satsight.ephemeris.oem`.
"""

from __future__ import annotations

import calendar
import logging
import math
import re

import numpy as np
from skyfield.timelib import Time

from satsight.ephemeris.oem_ephemeris import GAP_FACTOR, OemEphemeris, OemSegment, find_gaps
from satsight.ephemeris.sun_moon import gcrs_from_eme2000
from satsight.ephemeris.time import SECONDS_PER_DAY, timescale
from satsight.errors import SatsightError

log = logging.getLogger(__name__)

DEFAULT_INTERPOLATION = "LAGRANGE"
DEFAULT_DEGREE = 7

_GCRS_FRAMES = ("GCRF", "ICRF")
_EME2000_FRAMES = ("EME2000", "J2000")
_TIME_SYSTEMS = ("UTC", "TAI", "TT", "GPS", "TDB")
_EPOCH_RE = re.compile(
    r"^(?P<year>\d{4})-(?:(?P<month>\d{2})-(?P<day>\d{2})|(?P<doy>\d{3}))"
    r"T(?P<hour>\d{2}):(?P<minute>\d{2}):(?P<second>\d{2}(?:\.\d*)?)Z?$"
)


def oem_error(source: str, line_no: int | None, message: str) -> SatsightError:
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


def epoch_fields(
    text: str, source: str, line_no: int, keyword: str = "epoch"
) -> tuple[int, int, int, int, int, float]:
    """(year, month, day, hour, minute, second) of an OEM epoch, checked against the
    calendar (month lengths, leap years); ``keyword`` names the field in messages."""
    m = _EPOCH_RE.match(text)
    if m is None:
        raise oem_error(
            source,
            line_no,
            f"{keyword} {text!r} is not YYYY-MM-DDThh:mm:ss[.fff] or YYYY-DDDThh:mm:ss[.fff]",
        )
    year = int(m["year"])
    if m["doy"] is not None:
        month, day = 1, int(m["doy"])  # skyfield carries day-of-year past January
        days_in_year = 366 if calendar.isleap(year) else 365
        if not 1 <= day <= days_in_year:
            raise oem_error(
                source,
                line_no,
                f"{keyword} {text!r}: day of year {day} does not exist ({year} has "
                f"{days_in_year} days); correct the date",
            )
    else:
        month, day = int(m["month"]), int(m["day"])
        if not 1 <= month <= 12:
            raise oem_error(source, line_no, f"{keyword} {text!r}: month {month} does not exist")
        days_in_month = calendar.monthrange(year, month)[1] if year >= 1 else 31
        if not 1 <= day <= days_in_month:
            raise oem_error(
                source,
                line_no,
                f"{keyword} {text!r}: {year:04d}-{month:02d} has {days_in_month} days, so day "
                f"{day} does not exist; correct the date",
            )
    hour, minute, second = int(m["hour"]), int(m["minute"]), float(m["second"])
    if hour > 23 or minute > 59 or second >= 61.0:
        raise oem_error(source, line_no, f"{keyword} {text!r}: time of day out of range")
    return year, month, day, hour, minute, second


# One segment as read: metadata, (line, fields) of its states, the META_START line, and
# the line of each metadata keyword.
RawSegment = tuple[dict[str, str], list[tuple[int, list[str]]], int, dict[str, int]]


def _check_value_counts(data: list[tuple[int, list[str]]], source: str) -> None:
    """Every state line of a segment holds the same number of values (6, or 9 with
    accelerations); else an error naming the first line that differs."""
    first_no, first = data[0]
    for no, parts in data:
        if len(parts) != len(first):
            raise oem_error(
                source,
                no,
                f"this state line holds {len(parts) - 1} values but the segment's first state "
                f"line (line {first_no}) holds {len(first) - 1}; within a segment every state "
                "line gives 6 values (position, velocity) or every one 9 (with accelerations)",
            )


def build_ephemeris(
    header: dict[str, str], raw_segments: list[RawSegment], source: str
) -> OemEphemeris:
    """The ephemeris of an OEM's header keywords and its segments as read, each segment
    checked and its states converted to GCRS and SI; raises SatsightError naming the line."""
    built = []
    reference: Time | None = None
    for meta, data, meta_line, keyword_lines in raw_segments:
        if meta["CENTER_NAME"].upper() != "EARTH":
            raise oem_error(
                source, meta_line, f"CENTER_NAME {meta['CENTER_NAME']!r}; only EARTH is accepted"
            )
        frame = meta["REF_FRAME"].upper()
        if frame not in _GCRS_FRAMES + _EME2000_FRAMES:
            raise oem_error(
                source,
                meta_line,
                f"REF_FRAME {meta['REF_FRAME']!r} is not supported; use GCRF, ICRF or EME2000",
            )
        time_system = meta["TIME_SYSTEM"].upper()
        if time_system not in _TIME_SYSTEMS:
            raise oem_error(
                source,
                meta_line,
                f"TIME_SYSTEM {meta['TIME_SYSTEM']!r} is not supported; use "
                f"{', '.join(_TIME_SYSTEMS)}",
            )
        interpolation = meta.get("INTERPOLATION", DEFAULT_INTERPOLATION).upper()
        if interpolation not in ("LAGRANGE", "HERMITE", "LINEAR"):
            raise oem_error(
                source,
                meta_line,
                f"INTERPOLATION {meta['INTERPOLATION']!r}; use LAGRANGE, HERMITE or LINEAR",
            )
        try:
            degree = int(meta.get("INTERPOLATION_DEGREE", 1 if interpolation == "LINEAR" else 7))
        except ValueError:
            raise oem_error(
                source, meta_line, f"INTERPOLATION_DEGREE {meta['INTERPOLATION_DEGREE']!r}"
            ) from None
        if not 1 <= degree <= 32:
            raise oem_error(source, meta_line, f"INTERPOLATION_DEGREE {degree} outside 1-32")
        if interpolation == "LINEAR":
            interpolation, degree = "LAGRANGE", 1
        if len(data) < 2:
            raise oem_error(
                source, meta_line, f"a segment needs at least 2 states; got {len(data)}"
            )
        bounds = {
            key: meta.get(key)
            for key in ("START_TIME", "STOP_TIME", "USEABLE_START_TIME", "USEABLE_STOP_TIME")
        }
        bounds["USEABLE_START_TIME"] = bounds["USEABLE_START_TIME"] or bounds["START_TIME"]
        bounds["USEABLE_STOP_TIME"] = bounds["USEABLE_STOP_TIME"] or bounds["STOP_TIME"]
        if "REF_FRAME_EPOCH" in meta:
            epoch_fields(
                meta["REF_FRAME_EPOCH"], source, keyword_lines["REF_FRAME_EPOCH"], "REF_FRAME_EPOCH"
            )
        # START_TIME and STOP_TIME come first: a default USEABLE_* is checked as them.
        fields = [
            epoch_fields(bounds[k], source, keyword_lines.get(k, meta_line), k) for k in bounds
        ]
        fields += [epoch_fields(parts[0], source, no) for no, parts in data]
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
            raise oem_error(source, data[int(bad[0]) + 1][0], "epochs must increase strictly")
        _check_value_counts(data, source)
        try:
            values = np.array([[float(x) for x in parts[1:]] for _, parts in data])
        except ValueError:
            for no, parts in data:
                for x in parts[1:]:
                    try:
                        float(x)
                    except ValueError:
                        raise oem_error(source, no, f"{x!r} is not a number") from None
            raise
        if not np.all(np.isfinite(values)):
            row = int(np.flatnonzero(~np.all(np.isfinite(values), axis=1))[0])
            raise oem_error(source, data[row][0], "a state holds a non-finite value")
        if start > stop or not start <= ustart <= ustop <= stop:
            raise oem_error(
                source,
                meta_line,
                "need START_TIME <= USEABLE_START_TIME <= USEABLE_STOP_TIME <= STOP_TIME",
            )
        tolerance = 1e-6
        if t_s[0] < start - tolerance or t_s[-1] > stop + tolerance:
            raise oem_error(source, meta_line, "states lie outside START_TIME - STOP_TIME")
        lines = np.array([no for no, _ in data], dtype=np.int64)
        _check_held_span(source, meta, keyword_lines, meta_line, t_s, lines, ustart, ustop)
        gaps = find_gaps(t_s)
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
        raise oem_error(
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
