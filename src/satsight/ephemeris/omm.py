"""CCSDS OMM (Orbit Mean-elements Message, CCSDS 502.0-B) records of SGP4 mean elements.

One or more records, as KVN (``KEY = value`` lines), XML (the CCSDS NDM/XML layout), or
the JSON and CSV flavours that CelesTrak serves (the same keywords as flat records). When
present, ``CENTER_NAME`` must be ``EARTH``, ``REF_FRAME`` ``TEME``, ``TIME_SYSTEM`` ``UTC``
and ``MEAN_ELEMENT_THEORY`` ``SGP4`` (or ``SGP/SGP4``). Values are checked before SGP4
sees them, naming the field (and the line, for KVN): ``EPOCH`` must be a real calendar
date and time of day; ``NORAD_CAT_ID`` an integer 0-339999 (the Alpha-5 range SGP4 can
store); ``ECCENTRICITY`` in [0, 1); ``MEAN_MOTION`` > 0 rev/day; ``INCLINATION`` in
[0, 180] deg; every other number finite. The elements are initialised with WGS-72 like a
TLE's (:mod:`satsight.ephemeris.sgp4_orbit`).
"""

from __future__ import annotations

import calendar
import csv
import io
import json
import math
import re
import xml.etree.ElementTree as ET
from datetime import datetime

from sgp4.api import WGS72, Satrec

from satsight.ephemeris.sgp4_orbit import Sgp4Orbit, orbit_from_satrec
from satsight.ephemeris.time import SECONDS_PER_DAY
from satsight.errors import SatsightError

# sgp4init's epoch: days since 1949-12-31 00:00 UTC.
_SGP4_EPOCH0 = datetime(1949, 12, 31)
# MEAN_MOTION_DOT (rev/day^2) and MEAN_MOTION_DDOT (rev/day^3) to sgp4init's rad/min^2, ^3.
_NDOT_UNITS = 1_036_800.0 / math.pi
_NDDOT_UNITS = 2_985_984_000.0 / 2.0 / math.pi

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
    return orbit_from_satrec(
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
