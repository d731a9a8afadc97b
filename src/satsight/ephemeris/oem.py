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

import re
from pathlib import Path

import numpy as np
from skyfield.timelib import Time

from satsight.ephemeris.oem_ephemeris import OemEphemeris
from satsight.ephemeris.oem_segments import (
    DEFAULT_DEGREE,
    DEFAULT_INTERPOLATION,
    RawSegment,
    build_ephemeris,
    epoch_fields,
    oem_error,
)
from satsight.ephemeris.time import format_epoch_utc
from satsight.errors import SatsightError

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
_KVN_RE = re.compile(r"^([A-Z0-9_]+)\s*=\s*(.*?)\s*$")


def parse_oem(text: str, source: str = "OEM") -> OemEphemeris:
    """Read the KVN text of an OEM (see the module docstring for what is accepted)."""
    lines = text.splitlines()
    header: dict[str, str] = {}
    keyword_lines: dict[str, int] = {}  # the line of each keyword of the current block
    header_lines: dict[str, int] = keyword_lines
    raw_segments: list[RawSegment] = []
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
                raise oem_error(source, no, "META_START inside a metadata block")
            if state == "header":
                if "CCSDS_OEM_VERS" not in header:
                    raise oem_error(source, no, "the header must start with CCSDS_OEM_VERS")
            else:
                raw_segments.append((meta, data, meta_line, keyword_lines))
            meta, data, meta_line, state = {}, [], no, "meta"
            keyword_lines = {}
            continue
        if line == "META_STOP":
            if state != "meta":
                raise oem_error(source, no, "META_STOP without META_START")
            missing = [k for k in _META_REQUIRED if k not in meta]
            if missing:
                raise oem_error(source, no, f"metadata lacks {', '.join(missing)}")
            state = "data"
            continue
        if line == "COVARIANCE_START":
            if state != "data":
                raise oem_error(source, no, "COVARIANCE_START outside a data block")
            state = "covariance"
            continue
        if state in ("header", "meta"):
            m = _KVN_RE.match(line)
            if m is None:
                raise oem_error(source, no, f"expected 'KEYWORD = value'; got {raw!r}")
            key, value = m.group(1), m.group(2)
            allowed = _HEADER_KEYS if state == "header" else _META_KEYS
            if key not in allowed:
                block = "header" if state == "header" else "metadata"
                raise oem_error(source, no, f"unknown {block} keyword {key!r}")
            target = header if state == "header" else meta
            if key in target:
                raise oem_error(source, no, f"{key} given twice")
            if state == "header" and not header and key != "CCSDS_OEM_VERS":
                raise oem_error(source, no, "the header must start with CCSDS_OEM_VERS")
            target[key] = value
            keyword_lines[key] = no
            continue
        # A data line: epoch x y z vx vy vz [ax ay az].
        parts = line.split()
        if len(parts) not in (7, 10):
            raise oem_error(
                source,
                no,
                f"a state line holds an epoch and 6 values (or 9 with accelerations); "
                f"got {len(parts) - 1} values: {raw!r}",
            )
        data.append((no, parts))
    if state == "header":
        raise oem_error(source, None, "no segment (META_START ... META_STOP and states) found")
    if state == "meta":
        raise oem_error(source, None, "the last metadata block has no META_STOP")
    if state == "covariance":
        raise oem_error(source, None, "a covariance block has no COVARIANCE_STOP")
    raw_segments.append((meta, data, meta_line, keyword_lines))
    if "CREATION_DATE" in header:
        epoch_fields(
            header["CREATION_DATE"], source, header_lines["CREATION_DATE"], "CREATION_DATE"
        )
    return build_ephemeris(header, raw_segments, source)


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
