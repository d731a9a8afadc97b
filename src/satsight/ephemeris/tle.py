"""Catalogued satellites: two-line element sets (TLE) and CCSDS OMM mean elements, SGP4.

A TLE or an OMM holds *mean* elements of the SGP4 theory (Hoots & Roehrich, Spacetrack
Report #3, 1980, with the corrections of Vallado, Crawford, Hujsak & Kelso, "Revisiting
Spacetrack Report #3", AIAA 2006-6753), not osculating ones: they are meaningful only when
propagated with SGP4, which gives positions in TEME (True Equator, Mean Equinox of date).
Here SGP4 is skyfield's ``EarthSatellite`` (the ``sgp4`` package, WGS-72 constants as the
element sets are fitted with, "improved" mode), and skyfield turns TEME into GCRS with its
own precession-nutation model; positions come out in m, velocities in m/s, shape (N, 3).

Accuracy: a TLE is good to about a kilometre at its epoch, and degrades by kilometres per
day as it ages (drag, solar activity). A propagation more than ``WARN_AGE_DAYS`` (7 d) from
the element epoch is logged as a warning; beyond ``MAX_AGE_DAYS`` (30 d) it is refused.

Inputs:

* **TLE**: 2 lines, or 3 with a name line first (the CelesTrak layout, an optional ``0 ``
  before the name); a file may hold several sets, and lines starting with ``#`` are
  comments. Each data line is 69 columns; column 69 is the checksum (the sum of the digits
  of columns 1-68, each ``-`` counting 1, modulo 10) and is verified; fields are checked by
  column, and errors name the line and the columns. Five-digit catalogue numbers and the
  Alpha-5 form (a letter first) are accepted.
* **OMM** (CCSDS 502.0-B, Orbit Mean-elements Message), one or more records, as KVN
  (``KEY = value`` lines), XML (the CCSDS NDM/XML layout), or the JSON and CSV flavours that
  CelesTrak serves (the same keywords as flat records). When present, ``CENTER_NAME`` must
  be ``EARTH``, ``REF_FRAME`` ``TEME``, ``TIME_SYSTEM`` ``UTC`` and ``MEAN_ELEMENT_THEORY``
  ``SGP4`` (or ``SGP/SGP4``). Values are checked before SGP4 sees them, naming the field
  (and the line, for KVN): ``EPOCH`` must be a real calendar date and time of day;
  ``NORAD_CAT_ID`` an integer 0-339999 (the Alpha-5 range SGP4 can store);
  ``ECCENTRICITY`` in [0, 1); ``MEAN_MOTION`` > 0 rev/day; ``INCLINATION`` in [0, 180]
  deg; every other number finite.

A TLE's epoch day of year must exist in its year (1 to 366.999..., 365.999... outside
leap years).
"""

from __future__ import annotations

import calendar
import csv
import io
import json
import logging
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np
from sgp4.api import WGS72, Satrec
from skyfield.sgp4lib import EarthSatellite
from skyfield.timelib import Time

from satsight.ephemeris.time import SECONDS_PER_DAY, format_epoch_utc, timescale
from satsight.errors import SatsightError

log = logging.getLogger(__name__)

# Propagating further than this from the element epoch is logged; beyond the limit, refused.
WARN_AGE_DAYS = 7.0
MAX_AGE_DAYS = 30.0
# A TLE or OMM file larger than this is not an element file.
MAX_FILE_BYTES = 20_000_000

TLE_LINE_LENGTH = 69
# WGS-72 Earth radius, km, the unit of sgp4's semi-major axis ``Satrec.a``.
_WGS72_RADIUS_KM = 6378.135
# sgp4init's epoch: days since 1949-12-31 00:00 UTC.
_SGP4_EPOCH0 = datetime(1949, 12, 31)
# MEAN_MOTION_DOT (rev/day^2) and MEAN_MOTION_DDOT (rev/day^3) to sgp4init's rad/min^2, ^3.
_NDOT_UNITS = 1_036_800.0 / math.pi
_NDDOT_UNITS = 2_985_984_000.0 / 2.0 / math.pi


@dataclass(frozen=True)
class Sgp4Orbit:
    """A satellite's SGP4 mean elements (from a TLE or an OMM), ready to propagate.

    name: the object's name ("" when the source gives none); catalog_number: the NORAD
    catalogue number as written (5 digits or Alpha-5); source: where the elements came
    from, for messages; satellite: skyfield's SGP4 propagator.
    """

    name: str
    catalog_number: str
    source: str
    satellite: EarthSatellite

    @property
    def satrec(self) -> Satrec:
        return self.satellite.model

    @property
    def epoch(self) -> Time:
        """The element epoch (UTC in the source), a scalar skyfield ``Time``."""
        return self.satellite.epoch

    @property
    def epoch_utc(self) -> str:
        """The element epoch as UTC ISO-8601 text with microseconds."""
        return format_epoch_utc(self.epoch, places=6)

    @property
    def mean_motion_rad_s(self) -> float:
        """The mean motion of the element set (Kozai's convention, as a TLE writes it), rad/s."""
        return float(self.satrec.no_kozai) / 60.0

    @property
    def mean_semi_major_axis_m(self) -> float:
        """The SGP4 mean semi-major axis, m (WGS-72 units), consistent with the mean motion."""
        return float(self.satrec.a) * _WGS72_RADIUS_KM * 1e3

    @property
    def period_s(self) -> float:
        """The period of the mean motion, s."""
        return 2.0 * math.pi / self.mean_motion_rad_s

    def age_days(self, times: Time) -> np.ndarray:
        """Signed days from the element epoch to ``times`` (TT days)."""
        epoch = self.epoch
        return (np.asarray(times.whole) - float(epoch.whole)) + (
            np.asarray(times.tt_fraction) - float(epoch.tt_fraction)
        )

    def check_age(self, times: Time) -> None:
        """Refuse times more than MAX_AGE_DAYS from the epoch; log those beyond WARN_AGE_DAYS."""
        age = np.atleast_1d(np.abs(self.age_days(times)))
        worst = float(np.max(age)) if age.size else 0.0
        if worst > MAX_AGE_DAYS:
            raise SatsightError(
                f"{self.source}: a requested time lies {worst:.1f} days from the element epoch "
                f"{self.epoch_utc}; SGP4 elements are refused beyond {MAX_AGE_DAYS:g} days (their "
                "error grows by kilometres per day); use an element set closer to the "
                "scenario's epoch_utc"
            )
        if worst > WARN_AGE_DAYS:
            log.warning(
                "%s: propagating %.1f days from the element epoch %s; SGP4 accuracy degrades "
                "beyond about %g days",
                self.source,
                worst,
                self.epoch_utc,
                WARN_AGE_DAYS,
            )

    def state_gcrs(self, times: Time) -> tuple[np.ndarray, np.ndarray]:
        """GCRS position (N, 3), m, and velocity (N, 3), m/s, at the skyfield ``times``.

        A scalar ``Time`` gives N = 1. Raises SatsightError beyond MAX_AGE_DAYS from the
        epoch or where SGP4 fails (e.g. the orbit has decayed).
        """
        if times.shape == ():
            times = timescale().tt_jd(np.atleast_1d(times.whole), np.atleast_1d(times.tt_fraction))
        self.check_age(times)
        geocentric = self.satellite.at(times)
        r = np.asarray(geocentric.position.m, dtype=np.float64).T
        v = np.asarray(geocentric.velocity.m_per_s, dtype=np.float64).T
        bad = ~np.all(np.isfinite(r), axis=1) | ~np.all(np.isfinite(v), axis=1)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            message = getattr(geocentric, "message", None)
            if isinstance(message, (list, tuple, np.ndarray)):
                message = message[i]
            raise SatsightError(
                f"{self.source}: SGP4 failed at {format_epoch_utc(times[i])}"
                + (f" ({message})" if message else "")
                + "; the element set cannot be propagated to that time"
            )
        return r, v


# --- TLE -----------------------------------------------------------------------------------


def tle_checksum(line: str) -> int:
    """The TLE checksum of columns 1-68 of ``line``: digits summed, '-' counts 1, mod 10."""
    total = 0
    for ch in line[:68]:
        if ch.isdigit():
            total += int(ch)
        elif ch == "-":
            total += 1
    return total % 10


# (first column, last column) 1-based inclusive, field name, pattern.
_NUMBER = r"[ +-]?\d*\.?\d+"
_IMPLIED = r"[ +-]?\d{0,5}[+-]\d"  # implied-decimal mantissa and exponent, e.g. " 38792-4"
_LINE1_FIELDS = (
    (1, 1, "line number", r"1"),
    (3, 7, "catalogue number", r"[ 0-9A-Z]\d{4}|\s*\d{1,5}"),
    (8, 8, "classification", r"[UCS ]"),
    (10, 17, "international designator", r"[ 0-9A-Z-]*"),
    (19, 20, "epoch year", r"\d{2}|\s\d"),
    (21, 32, "epoch day of year", r"\s*\d{1,3}\.\d+"),
    (34, 43, "first derivative of the mean motion", _NUMBER),
    (45, 52, "second derivative of the mean motion", _IMPLIED + r"|\s*0+|\s*"),
    (54, 61, "drag term (B*)", _IMPLIED + r"|\s*0+|\s*"),
    (63, 63, "ephemeris type", r"[0-9 ]"),
    (65, 68, "element set number", r"\s*\d*"),
)
_LINE2_FIELDS = (
    (1, 1, "line number", r"2"),
    (3, 7, "catalogue number", r"[ 0-9A-Z]\d{4}|\s*\d{1,5}"),
    (9, 16, "inclination (deg)", r"\s*\d{1,3}\.\d*"),
    (18, 25, "right ascension of the ascending node (deg)", r"\s*\d{1,3}\.\d*"),
    (27, 33, "eccentricity (implied leading decimal point)", r"\d{7}|\s*\d{1,7}"),
    (35, 42, "argument of perigee (deg)", r"\s*\d{1,3}\.\d*"),
    (44, 51, "mean anomaly (deg)", r"\s*\d{1,3}\.\d*"),
    (53, 63, "mean motion (rev/day)", r"\s*\d{1,2}\.\d+"),
    (64, 68, "revolution number at epoch", r"\s*\d*"),
)


def _tle_error(source: str, line_no: int, message: str) -> SatsightError:
    return SatsightError(f"{source}, line {line_no}: {message}")


def _check_tle_line(line: str, kind: int, source: str, line_no: int) -> str:
    line = line.rstrip()
    if len(line) != TLE_LINE_LENGTH:
        raise _tle_error(
            source,
            line_no,
            f"TLE line {kind} must be {TLE_LINE_LENGTH} columns (the last is the checksum); "
            f"it has {len(line)}: {line!r}",
        )
    fields = _LINE1_FIELDS if kind == 1 else _LINE2_FIELDS
    for first, last, name, pattern in fields:
        text = line[first - 1 : last]
        if re.fullmatch(pattern, text) is None:
            where = f"column {first}" if first == last else f"columns {first}-{last}"
            raise _tle_error(
                source, line_no, f"TLE line {kind}, {where} ({name}): unexpected {text!r}"
            )
    if not line[68].isdigit():
        raise _tle_error(
            source, line_no, f"TLE line {kind}, column 69 (checksum): {line[68]!r} is not a digit"
        )
    expected = tle_checksum(line)
    if int(line[68]) != expected:
        raise _tle_error(
            source,
            line_no,
            f"TLE line {kind}, column 69: checksum {line[68]} does not match the computed "
            f"{expected}; the line is corrupt (or was edited without updating the checksum)",
        )
    return line


def _check_tle_epoch(line1: str, source: str, line_no: int) -> None:
    """Refuse an epoch day of year that does not exist in the epoch's year (columns 19-32;
    two-digit years 57-99 are 1957-1999, 00-56 are 2000-2056, as in sgp4)."""
    two_digit = int(line1[18:20])
    year = two_digit + (1900 if two_digit >= 57 else 2000)
    day = float(line1[20:32])
    days_in_year = 366 if calendar.isleap(year) else 365
    if not 1.0 <= day < days_in_year + 1.0:
        raise _tle_error(
            source,
            line_no,
            f"TLE line 1, columns 21-32 (epoch day of year): day {day:g} does not exist in "
            f"{year} (expected 1 <= day < {days_in_year + 1}; day 1.0 is 1 January 00:00 UTC)",
        )


def _orbit_from_satrec(
    satrec: Satrec, name: str, source: str, catalog_number: str | None = None
) -> Sgp4Orbit:
    if satrec.error:
        raise SatsightError(
            f"{source}: SGP4 cannot initialise these elements (sgp4 error {satrec.error}); "
            "check the mean motion and eccentricity"
        )
    satellite = EarthSatellite.from_satrec(satrec, timescale())
    satellite.name = name
    number = catalog_number or str(getattr(satrec, "satnum_str", "") or satrec.satnum)
    return Sgp4Orbit(name=name, catalog_number=number, source=source, satellite=satellite)


def parse_tle(text: str | list[str] | tuple[str, ...], source: str = "TLE") -> list[Sgp4Orbit]:
    """Every element set in ``text`` (a string or a list of lines), in order.

    Accepts 2-line sets and 3-line sets (a name line first, ``0 `` prefix optional); blank
    lines and lines starting with ``#`` (comments) are ignored. Raises SatsightError naming
    the line (1-based, in ``text``) and the columns of the first malformed field, a wrong
    checksum, or a line 1 without its line 2.
    """
    lines = text.splitlines() if isinstance(text, str) else [str(x) for x in text]
    numbered = [
        (i + 1, line)
        for i, line in enumerate(lines)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    orbits: list[Sgp4Orbit] = []
    k = 0
    while k < len(numbered):
        no, line = numbered[k]
        name = ""
        if not line.startswith("1 "):
            if line.startswith("2 "):
                raise _tle_error(source, no, "TLE line 2 without a line 1 before it")
            name = line.strip()
            name = name[2:].strip() if name.startswith("0 ") else name
            k += 1
            if k >= len(numbered):
                raise _tle_error(source, no, f"name line {name!r} is not followed by a TLE")
            no, line = numbered[k]
            if not line.startswith("1 "):
                raise _tle_error(
                    source, no, f"expected TLE line 1 (starting '1 ') after the name; got {line!r}"
                )
        line1 = _check_tle_line(line, 1, source, no)
        if k + 1 >= len(numbered):
            raise _tle_error(source, no, "TLE line 1 is not followed by its line 2")
        no2, line = numbered[k + 1]
        if not line.startswith("2 "):
            raise _tle_error(source, no2, f"expected TLE line 2 (starting '2 '); got {line!r}")
        line2 = _check_tle_line(line, 2, source, no2)
        if line1[2:7] != line2[2:7]:
            raise _tle_error(
                source,
                no2,
                f"TLE line 2, columns 3-7: catalogue number {line2[2:7]!r} differs from line 1's "
                f"{line1[2:7]!r}",
            )
        _check_tle_epoch(line1, source, no)
        satrec = Satrec.twoline2rv(line1, line2, WGS72)
        orbits.append(_orbit_from_satrec(satrec, name, f"{source} (line {no})"))
        k += 2
    if not orbits:
        raise SatsightError(f"{source}: no TLE found (expected lines starting '1 ' and '2 ')")
    return orbits


# --- OMM -----------------------------------------------------------------------------------

_OMM_REQUIRED = (
    "EPOCH",
    "MEAN_MOTION",
    "ECCENTRICITY",
    "INCLINATION",
    "RA_OF_ASC_NODE",
    "ARG_OF_PERICENTER",
    "MEAN_ANOMALY",
    "NORAD_CAT_ID",
    "BSTAR",
)
_OMM_EXPECTED = {
    "CENTER_NAME": ("EARTH",),
    "REF_FRAME": ("TEME",),
    "TIME_SYSTEM": ("UTC",),
    "MEAN_ELEMENT_THEORY": ("SGP4", "SGP/SGP4"),
}
_OMM_EPOCH_RE = re.compile(
    r"^(\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)Z?$|^(\d{4})-(\d{3})T(\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)Z?$"
)
_KVN_RE = re.compile(r"^\s*([A-Z0-9_]+)\s*=\s*(.*?)\s*$")


def _strip_units(value: str) -> str:
    """'15.5 [rev/day]' -> '15.5' (KVN values may carry their unit in brackets)."""
    return re.sub(r"\s*\[[^\]]*\]\s*$", "", value).strip()


def parse_omm_kvn(text: str) -> list[dict[str, str]]:
    """OMM records from CCSDS KVN text: ``KEY = value`` lines, ``COMMENT`` lines skipped; a
    new record starts at each ``CCSDS_OMM_VERS`` (or at a repeated ``EPOCH``)."""
    return _parse_omm_kvn_lines(text)[0]


def _parse_omm_kvn_lines(text: str) -> tuple[list[dict[str, str]], list[dict[str, int]]]:
    """``parse_omm_kvn``'s records, and for each the line (1-based) of every keyword."""
    records: list[dict[str, str]] = []
    record_lines: list[dict[str, int]] = []
    current: dict[str, str] = {}
    lines: dict[str, int] = {}
    for no, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("COMMENT"):
            continue
        m = _KVN_RE.match(line)
        if m is None:
            raise SatsightError(f"OMM line {no}: expected 'KEYWORD = value'; got {raw!r}")
        key, value = m.group(1), _strip_units(m.group(2))
        if key == "CCSDS_OMM_VERS" or key in current:
            if current:
                records.append(current)
                record_lines.append(lines)
            current, lines = {}, {}
        current[key] = value
        lines[key] = no
    if current:
        records.append(current)
        record_lines.append(lines)
    return records, record_lines


def parse_omm_xml(text: str) -> list[dict[str, str]]:
    """OMM records from CCSDS NDM/XML (``<segment>`` with ``<metadata>`` and ``<data>``);
    document type declarations are refused (no entity expansion)."""
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise SatsightError("OMM XML: document type declarations are not accepted")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise SatsightError(f"OMM XML is not well-formed: {e}") from None
    records = []
    for element in root.iter():
        if _local(element.tag) != "segment":
            continue
        fields: dict[str, str] = {}
        for child in element.iter():
            if len(child) == 0 and child.text is not None and child.text.strip():
                fields[_local(child.tag)] = child.text.strip()
        records.append(fields)
    return records


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def parse_omm_json(text: str) -> list[dict[str, str]]:
    """OMM records from JSON: one object or a list of objects of OMM keywords (CelesTrak)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise SatsightError(f"OMM JSON is not valid: {e}") from None
    items = data if isinstance(data, list) else [data]
    if not all(isinstance(item, dict) for item in items):
        raise SatsightError("OMM JSON must be an object or a list of objects of OMM keywords")
    return [{str(k): str(v) for k, v in item.items() if v is not None} for item in items]


def parse_omm_csv(text: str) -> list[dict[str, str]]:
    """OMM records from CSV with a header row of OMM keywords (CelesTrak)."""
    return [
        {k.strip(): v.strip() for k, v in row.items() if k and v is not None}
        for row in csv.DictReader(io.StringIO(text))
    ]


def _omm_epoch_days(value: str, source: str) -> float:
    """sgp4init's epoch (days since 1949-12-31 00:00 UTC) of an OMM ``EPOCH``, checked
    against the calendar; ``source`` names the record (and line) in messages."""
    m = _OMM_EPOCH_RE.match(value.strip())
    if m is None:
        raise SatsightError(
            f"{source}: EPOCH {value!r} is not YYYY-MM-DDThh:mm:ss[.fff] or YYYY-DDDThh:mm:ss"
        )
    if m.group(1):
        year, month, day = int(m.group(1)), int(m.group(2)), int(m.group(3))
        hour, minute, second = int(m.group(4)), int(m.group(5)), float(m.group(6))
        if not 1 <= month <= 12:
            raise SatsightError(f"{source}: EPOCH {value!r}: month {month} does not exist")
        days_in_month = calendar.monthrange(max(year, 1), month)[1]
        if year < 1 or not 1 <= day <= days_in_month:
            raise SatsightError(
                f"{source}: EPOCH {value!r}: {year:04d}-{month:02d} has {days_in_month} days, "
                f"so day {day} does not exist; correct the date"
            )
        date = datetime(year, month, day)
    else:
        year, doy = int(m.group(7)), int(m.group(8))
        hour, minute, second = int(m.group(9)), int(m.group(10)), float(m.group(11))
        days_in_year = 366 if calendar.isleap(year) else 365
        if year < 1 or not 1 <= doy <= days_in_year:
            raise SatsightError(
                f"{source}: EPOCH {value!r}: day of year {doy} does not exist ({year} has "
                f"{days_in_year} days); correct the date"
            )
        date = datetime.fromordinal(datetime(year, 1, 1).toordinal() + doy - 1)
    if hour > 23 or minute > 59 or second >= 60.0:
        raise SatsightError(
            f"{source}: EPOCH {value!r}: time of day out of range (hh 00-23, mm 00-59, ss below 60)"
        )
    days = (date - _SGP4_EPOCH0).days
    return days + (hour * 3600.0 + minute * 60.0 + second) / SECONDS_PER_DAY


# Ranges that SGP4 needs (beyond these sgp4init fails, overflows, or propagates NaN):
# (low, high, low included, high included, what to write).
_OMM_RANGES = {
    "NORAD_CAT_ID": (0.0, 339999.0, True, True, "an integer 0-339999 (the Alpha-5 range)"),
    "ECCENTRICITY": (0.0, 1.0, True, False, "0 <= e < 1 (a closed orbit)"),
    "MEAN_MOTION": (0.0, math.inf, False, False, "> 0 rev/day"),
    "INCLINATION": (0.0, 180.0, True, True, "0-180 deg"),
}


def orbit_from_omm(
    fields: dict[str, str], source: str = "OMM", lines: dict[str, int] | None = None
) -> Sgp4Orbit:
    """An ``Sgp4Orbit`` from one OMM record's keywords (mean elements in degrees and rev/day,
    BSTAR in 1/Earth radii), initialised with WGS-72 like a TLE.

    lines: the line of each keyword in the file (KVN), named in messages. Raises
    SatsightError for a missing keyword, an impossible EPOCH, a value that is not a finite
    number, or one outside the range SGP4 needs (``_OMM_RANGES``)."""
    lines = lines or {}

    def where(key: str) -> str:
        return f"{source}, line {lines[key]}" if key in lines else source

    missing = [k for k in _OMM_REQUIRED if k not in fields]
    if missing:
        raise SatsightError(f"{source}: missing OMM keyword(s) {', '.join(missing)}")
    for key, allowed in _OMM_EXPECTED.items():
        if key in fields and fields[key].strip().upper() not in allowed:
            raise SatsightError(
                f"{where(key)}: {key} = {fields[key]!r}; SGP4 elements need {' or '.join(allowed)}"
            )

    def number(key: str, default: float | None = None) -> float:
        if key not in fields and default is not None:
            return default
        try:
            value = float(_strip_units(fields[key]))
        except ValueError:
            raise SatsightError(f"{where(key)}: {key} = {fields[key]!r} is not a number") from None
        if not math.isfinite(value):
            raise SatsightError(f"{where(key)}: {key} = {fields[key]!r} must be a finite number")
        if key in _OMM_RANGES:
            low, high, low_in, high_in, expected = _OMM_RANGES[key]
            above = value >= low if low_in else value > low
            below = value <= high if high_in else value < high
            whole = key != "NORAD_CAT_ID" or value == math.floor(value)
            if not (above and below and whole):
                raise SatsightError(
                    f"{where(key)}: {key} = {fields[key]!r} is out of range; SGP4 needs {expected}"
                )
        return value

    epoch_days = _omm_epoch_days(fields["EPOCH"], where("EPOCH"))
    catalog_number = int(number("NORAD_CAT_ID"))
    satrec = Satrec()
    satrec.sgp4init(
        WGS72,
        "i",
        catalog_number,
        epoch_days,
        number("BSTAR"),
        number("MEAN_MOTION_DOT", 0.0) / _NDOT_UNITS,
        number("MEAN_MOTION_DDOT", 0.0) / _NDDOT_UNITS,
        number("ECCENTRICITY"),
        math.radians(number("ARG_OF_PERICENTER")),
        math.radians(number("INCLINATION")),
        math.radians(number("MEAN_ANOMALY")),
        number("MEAN_MOTION") * 2.0 * math.pi / 1440.0,
        math.radians(number("RA_OF_ASC_NODE")),
    )
    # The number as decimal digits (sgp4 stores 5 characters: Alpha-5 above 99999).
    return _orbit_from_satrec(
        satrec, fields.get("OBJECT_NAME", ""), source, catalog_number=str(catalog_number)
    )


def parse_omm(text: str, source: str = "OMM") -> list[Sgp4Orbit]:
    """Every OMM record in ``text``, whose form (XML, JSON, KVN or CSV) is recognised from
    its first characters."""
    head = text.lstrip()
    record_lines: list[dict[str, int]] = []  # known for KVN only
    if head.startswith("<"):
        records = parse_omm_xml(text)
    elif head.startswith(("{", "[")):
        records = parse_omm_json(text)
    elif re.match(r"^(CCSDS_OMM_VERS|COMMENT)\b", head) or _KVN_RE.match(head.split("\n")[0]):
        records, record_lines = _parse_omm_kvn_lines(text)
    else:
        records = parse_omm_csv(text)
    if not records:
        raise SatsightError(f"{source}: no OMM record found")
    if len(record_lines) != len(records):
        record_lines = [{} for _ in records]
    return [
        orbit_from_omm(r, f"{source} (record {i + 1})", lines)
        for i, (r, lines) in enumerate(zip(records, record_lines, strict=True))
    ]


# --- files and selection ---------------------------------------------------------------------


def _read_text(path: Path, what: str) -> str:
    path = Path(path)
    if not path.is_file():
        raise SatsightError(f"{what} file not found: {path}")
    if path.stat().st_size > MAX_FILE_BYTES:
        raise SatsightError(f"{path}: larger than {MAX_FILE_BYTES} bytes; not a {what} file")
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise SatsightError(f"{path}: not UTF-8 text; expected a {what} file") from None


def read_tle_file(path: str | Path) -> list[Sgp4Orbit]:
    """Every TLE in the text file ``path``."""
    return parse_tle(_read_text(Path(path), "TLE"), source=str(path))


def read_omm_file(path: str | Path) -> list[Sgp4Orbit]:
    """Every OMM record in the file ``path`` (KVN, XML, JSON or CSV)."""
    return parse_omm(_read_text(Path(path), "OMM"), source=str(path))


def select_orbit(orbits: list[Sgp4Orbit], satellite: str | int | None, source: str) -> Sgp4Orbit:
    """The one element set named by ``satellite`` (its name, case-insensitive, or its
    catalogue number); with ``satellite`` None the source must hold exactly one."""
    if satellite is None:
        if len(orbits) == 1:
            return orbits[0]
        listed = ", ".join(f"{o.name or '?'} ({o.catalog_number})" for o in orbits[:10])
        raise SatsightError(
            f"{source} holds {len(orbits)} element sets ({listed}"
            f"{', ...' if len(orbits) > 10 else ''}); choose one with 'satellite' (name or "
            "catalogue number)"
        )
    wanted = str(satellite).strip()
    found = [
        o
        for o in orbits
        if o.name.strip().upper() == wanted.upper()
        or o.catalog_number.strip().lstrip("0") == wanted.lstrip("0")
    ]
    if not found:
        raise SatsightError(f"{source}: no element set named or numbered {wanted!r}")
    if len(found) > 1:
        # Several sets of the same object: the latest epoch.
        return max(found, key=lambda o: float(o.epoch.tt))
    return found[0]
