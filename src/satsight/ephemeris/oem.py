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
  ``STOP_TIME``) bound where a segment is used; a time outside every segment is refused.
  Where segments overlap, the first one listed that holds the time is used.

Covariance blocks (``COVARIANCE_START`` ... ``COVARIANCE_STOP``) and ``COMMENT`` lines are
skipped. The parser is strict: an unknown keyword, a data line with a wrong number of
values, or epochs that do not increase are errors naming the line.

Internally epochs are elapsed seconds (TT) from the message's first epoch, kept as a whole
TT Julian day plus a fraction so that sub-microsecond resolution survives.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
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


def _epoch_fields(text: str, source: str, line_no: int) -> tuple[int, int, int, int, int, float]:
    m = _EPOCH_RE.match(text)
    if m is None:
        raise _error(
            source,
            line_no,
            f"epoch {text!r} is not YYYY-MM-DDThh:mm:ss[.fff] or YYYY-DDDThh:mm:ss[.fff]",
        )
    year = int(m["year"])
    if m["doy"] is not None:
        month, day = 1, int(m["doy"])  # skyfield carries day-of-year past January
        if not 1 <= day <= 366:
            raise _error(source, line_no, f"epoch {text!r}: day of year {day} outside 1-366")
    else:
        month, day = int(m["month"]), int(m["day"])
        if not (1 <= month <= 12 and 1 <= day <= 31):
            raise _error(source, line_no, f"epoch {text!r}: month or day out of range")
    hour, minute, second = int(m["hour"]), int(m["minute"]), float(m["second"])
    if hour > 23 or minute > 59 or second >= 61.0:
        raise _error(source, line_no, f"epoch {text!r}: time of day out of range")
    return year, month, day, hour, minute, second


@dataclass(frozen=True)
class OemSegment:
    """One segment: its metadata and its states, converted to GCRS and SI.

    t_s (N,): TT seconds after the message reference epoch; r_m (N, 3), v_m_s (N, 3): GCRS
    position and velocity; a_m_s2 (N, 3) or None: acceleration as given (GCRS axes).
    start_s, stop_s, useable_start_s, useable_stop_s: the segment's bounds, same scale.
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

    def holds(self, t_s: np.ndarray) -> np.ndarray:
        return (t_s >= self.useable_start_s) & (t_s <= self.useable_stop_s)

    def interpolate(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """GCRS position (M, 3), m, and velocity (M, 3), m/s, at t_s (M,) inside the segment."""
        if self.interpolation == "HERMITE":
            return _hermite(self.t_s, self.r_m, self.v_m_s, t_s, self.degree)
        return (
            _lagrange(self.t_s, self.r_m, t_s, self.degree),
            _lagrange(self.t_s, self.v_m_s, t_s, self.degree),
        )


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
        """The first instant the message may be used: its first segment's useable start."""
        return self.time_at(min(s.useable_start_s for s in self.segments))

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
            spans = "; ".join(
                f"{format_epoch_utc(self.time_at(s.useable_start_s), 3)} to "
                f"{format_epoch_utc(self.time_at(s.useable_stop_s), 3)}"
                for s in self.segments
            )
            when = format_epoch_utc(self.time_at(float(t[i])), 3)
            raise SatsightError(
                f"{self.source}: {when} (UTC) lies outside the ephemeris's useable span(s) "
                f"{spans}; choose epoch_utc and the sampler's span inside them"
            )
        return r, v

    def first_state_gcrs(self) -> tuple[np.ndarray, np.ndarray]:
        """The first state of the first segment, GCRS m and m/s."""
        return self.segments[0].r_m[0].copy(), self.segments[0].v_m_s[0].copy()


def parse_oem(text: str, source: str = "OEM") -> OemEphemeris:
    """Read the KVN text of an OEM (see the module docstring for what is accepted)."""
    lines = text.splitlines()
    header: dict[str, str] = {}
    raw_segments: list[tuple[dict[str, str], list[tuple[int, list[str]]], int]] = []
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
                raw_segments.append((meta, data, meta_line))
            meta, data, meta_line, state = {}, [], no, "meta"
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
    raw_segments.append((meta, data, meta_line))
    return _build(header, raw_segments, source)


def _build(
    header: dict[str, str],
    raw_segments: list[tuple[dict[str, str], list[tuple[int, list[str]]], int]],
    source: str,
) -> OemEphemeris:
    built = []
    reference: Time | None = None
    for meta, data, meta_line in raw_segments:
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
        fields = [_epoch_fields(bounds[k], source, meta_line) for k in bounds]
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
            raise _error(source, meta_line, "a state holds a non-finite value")
        if start > stop or not start <= ustart <= ustop <= stop:
            raise _error(
                source,
                meta_line,
                "need START_TIME <= USEABLE_START_TIME <= USEABLE_STOP_TIME <= STOP_TIME",
            )
        tolerance = 1e-6
        if t_s[0] < start - tolerance or t_s[-1] > stop + tolerance:
            raise _error(source, meta_line, "states lie outside START_TIME - STOP_TIME")
        r = values[:, 0:3] * 1e3
        v = values[:, 3:6] * 1e3
        a = values[:, 6:9] * 1e3 if values.shape[1] == 9 else None
        if len({len(parts) for _, parts in data}) > 1:
            raise _error(source, meta_line, "mixed state lines with and without accelerations")
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
            )
        )
    return OemEphemeris(
        header=dict(header), segments=tuple(built), reference=reference, source=source
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
