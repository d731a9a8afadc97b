"""Two-line element sets (TLE), read and checked column by column; element files (TLE or
OMM) and the choice of one set among them.

A TLE holds SGP4 mean elements, propagated by :mod:`satsight.ephemeris.sgp4_orbit`; OMM
records are read by :mod:`satsight.ephemeris.omm`.

* **TLE**: 2 lines, or 3 with a name line first (the CelesTrak layout, an optional ``0 ``
  before the name); a file may hold several sets, and lines starting with ``#`` are
  comments. Each data line is 69 columns; column 69 is the checksum (the sum of the digits
  of columns 1-68, each ``-`` counting 1, modulo 10) and is verified; fields are checked by
  column, and errors name the line and the columns. Five-digit catalogue numbers and the
  Alpha-5 form (a letter first) are accepted.

A TLE's epoch day of year must exist in its year (1 to 366.999..., 365.999... outside
leap years).
"""

from __future__ import annotations

import calendar
import re
from pathlib import Path

from sgp4.api import WGS72, Satrec

from satsight.ephemeris.omm import parse_omm
from satsight.ephemeris.sgp4_orbit import Sgp4Orbit, orbit_from_satrec
from satsight.errors import SatsightError

# A TLE or OMM file larger than this is not an element file.
MAX_FILE_BYTES = 20_000_000

TLE_LINE_LENGTH = 69


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
        orbits.append(orbit_from_satrec(satrec, name, f"{source} (line {no})"))
        k += 2
    if not orbits:
        raise SatsightError(f"{source}: no TLE found (expected lines starting '1 ' and '2 ')")
    return orbits


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
