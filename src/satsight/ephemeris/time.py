"""Epochs: UTC ISO-8601 strings in, skyfield ``Time`` objects out, fully offline.

Time scales:

* **Input is UTC** (Coordinated Universal Time, the civil scale with leap seconds), written
  as ISO 8601 ``YYYY-MM-DDTHH:MM[:SS[.fff...]][Z|+00:00]``, e.g. ``"2025-03-20T12:00:00Z"``.
  A missing zone suffix means UTC; no other offsets are accepted. ``23:59:60`` is accepted
  only on a day that ends with a leap second.
* **The ephemeris runs on TDB** (Barycentric Dynamical Time, the argument of the JPL
  ephemerides) and skyfield also keeps **TT** (Terrestrial Time, TT = TAI + 32.184 s). TDB
  differs from TT by a periodic term below 1.7 ms; skyfield derives it from TT internally.
* **Offsets are elapsed SI seconds** (TT seconds). Across a leap second the UTC labels of
  ``epoch + offset`` advance by one second less than ``offset``: the clock that drives the
  frames never stops or jumps.

Leap seconds (UTC -> TAI) come from the table built into skyfield
(``skyfield/data/iers.npz``, built by skyfield's maintainers from the IERS ``finals2000A.all``
and Bulletin C). In skyfield 1.55 it lists every leap second up to the one inserted at the
end of 2016-12-31, after which TAI - UTC = 37 s; none has been announced since (IERS
Bulletin C). For dates after the table skyfield holds TAI - UTC at its last value, 37 s:
correct unless the IERS announces a new leap second, in which case UTC epochs after it
would be read 1 s late until skyfield (and so this table) is updated. The same file holds
daily Delta T = TT - UT1 from 1973 to early 2027; beyond it skyfield switches to the
long-term Delta T model of Morrison, Stephenson, Hohenkerk & Zawilski (Proc. R. Soc. A 477,
20200776, 2021). Delta T matters only for the Earth's rotation angle (UT1), not for the
Sun and Moon positions in GCRS.

Nothing is downloaded: the timescale is built with ``builtin=True`` and the
``skyfield-data`` package (``skyfield_data/data``) supplies the planetary ephemeris; see
:mod:`satsight.ephemeris.sun_moon`.
"""

from __future__ import annotations

import calendar
import datetime as _dt
import re
from functools import lru_cache
from pathlib import Path

import numpy as np
from skyfield.api import Loader
from skyfield.timelib import Time, Timescale

from satsight.errors import SatsightError

SECONDS_PER_DAY = 86_400.0

ISO_FORMAT = "YYYY-MM-DDTHH:MM[:SS[.fff...]][Z]"

_ISO_RE = re.compile(
    r"^(?P<year>\d{4})-(?P<month>\d{2})-(?P<day>\d{2})"
    r"T(?P<hour>\d{2}):(?P<minute>\d{2})"
    r"(?::(?P<second>\d{2}(?:\.\d+)?))?"
    r"(?:Z|\+00:00)?$"
)

# Julian Date of 0001-01-01T00:00 (proleptic Gregorian ordinal 1), for leap-day checks.
_JD_OF_ORDINAL_ZERO = 1_721_424.5


def skyfield_data_dir() -> Path:
    """The directory of the files shipped by the ``skyfield-data`` package.

    It is located from the package itself rather than with
    ``skyfield_data.get_skyfield_data_path()``, which warns whenever one of its files is past
    the maintainers' expiry date; satsight uses only ``de421.bsp`` from it (valid to
    2053-10-08), not its ``finals2000A.all``.
    """
    try:
        import skyfield_data
    except ImportError as e:  # pragma: no cover - a declared dependency
        raise SatsightError(
            "the package skyfield-data is not installed; install it with "
            "'pip install skyfield-data' (it ships the offline ephemeris de421.bsp)"
        ) from e
    return Path(skyfield_data.__file__).resolve().parent / "data"


@lru_cache(maxsize=1)
def skyfield_loader() -> Loader:
    """A skyfield ``Loader`` rooted at the skyfield-data directory, with no download URLs.

    Its URL table is emptied, so a file that is not already on disk makes skyfield raise
    instead of fetching it.
    """
    loader = Loader(str(skyfield_data_dir()), verbose=False)
    loader.urls = {}
    return loader


@lru_cache(maxsize=1)
def timescale() -> Timescale:
    """The skyfield timescale from its built-in leap-second and Delta T tables (no network)."""
    return skyfield_loader().timescale(builtin=True)


def _bad_epoch(value: object, why: str) -> SatsightError:
    return SatsightError(
        f"epoch {value!r} is not a valid UTC ISO-8601 time ({why}); expected {ISO_FORMAT}, "
        "e.g. '2025-03-20T12:00:00Z'"
    )


def _ends_with_leap_second(ts: Timescale, year: int, month: int, day: int) -> bool:
    next_day = _dt.date(year, month, day) + _dt.timedelta(days=1)
    jd_next_midnight = next_day.toordinal() + _JD_OF_ORDINAL_ZERO
    return bool(np.any(np.asarray(ts.leap_dates) == jd_next_midnight))


def parse_epoch_utc(epoch_utc: str) -> Time:
    """One UTC ISO-8601 epoch string as a scalar skyfield ``Time``.

    ``epoch_utc``: e.g. ``"2025-03-20T12:00:00Z"``, ``"2025-03-20T12:00:00.125"``. Seconds
    keep every digit given (skyfield stores the date as a whole Julian day plus a fraction).
    Raises ``SatsightError`` naming the value and the expected format when it is malformed or
    not a real date and time.
    """
    if not isinstance(epoch_utc, str):
        raise _bad_epoch(epoch_utc, "not a string")
    m = _ISO_RE.match(epoch_utc.strip())
    if m is None:
        raise _bad_epoch(epoch_utc, "unrecognised layout")
    year, month, day = int(m["year"]), int(m["month"]), int(m["day"])
    hour, minute = int(m["hour"]), int(m["minute"])
    second = float(m["second"]) if m["second"] is not None else 0.0
    if not 1 <= month <= 12:
        raise _bad_epoch(epoch_utc, f"month {month} outside 1-12")
    last_day = calendar.monthrange(year, month)[1]
    if not 1 <= day <= last_day:
        raise _bad_epoch(epoch_utc, f"day {day} outside 1-{last_day}")
    if hour > 23 or minute > 59:
        raise _bad_epoch(epoch_utc, "hour or minute out of range")
    ts = timescale()
    if second >= 60.0:
        leap_ok = (
            second < 61.0
            and hour == 23
            and minute == 59
            and _ends_with_leap_second(ts, year, month, day)
        )
        if not leap_ok:
            raise _bad_epoch(epoch_utc, "seconds >= 60 outside a leap second")
    return ts.utc(year, month, day, hour, minute, second)


def epoch_times(epoch_utc: str, offsets_s: object) -> Time:
    """Times ``epoch + offset`` as one vector skyfield ``Time`` of shape (N,).

    ``epoch_utc``: UTC ISO-8601 string (see :func:`parse_epoch_utc`). ``offsets_s``: (N,)
    elapsed seconds (SI, i.e. TT seconds) after the epoch; a scalar counts as N = 1. Offsets
    are split into whole days and a remainder so that the sum keeps sub-microsecond precision
    over years.
    """
    offsets = np.atleast_1d(np.asarray(offsets_s, dtype=np.float64))
    if offsets.ndim != 1 or not np.all(np.isfinite(offsets)):
        raise SatsightError(
            f"offsets_s must be a finite scalar or 1-D array of seconds, got shape "
            f"{np.shape(offsets_s)}"
        )
    t0 = parse_epoch_utc(epoch_utc)
    days = np.floor(offsets / SECONDS_PER_DAY)
    rest_days = (offsets - days * SECONDS_PER_DAY) / SECONDS_PER_DAY
    whole = float(t0.whole) + days
    fraction = float(t0.tt_fraction) + rest_days
    return timescale().tt_jd(whole, fraction)


def format_epoch_utc(t: Time, places: int = 6) -> str | list[str]:
    """A skyfield ``Time`` as UTC ISO-8601 text ``YYYY-MM-DDTHH:MM:SS.ffffffZ``.

    ``places``: decimal places of the seconds. A vector ``Time`` gives a list of strings.
    Leap seconds print as ``23:59:60``.
    """
    return t.utc_iso(places=places)
