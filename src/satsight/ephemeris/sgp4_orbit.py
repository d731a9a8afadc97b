"""SGP4 mean elements of a catalogued satellite (from a TLE or an OMM), propagated to GCRS.

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
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from sgp4.api import Satrec
from skyfield.sgp4lib import EarthSatellite
from skyfield.timelib import Time

from satsight.ephemeris.time import format_epoch_utc, timescale
from satsight.errors import SatsightError

log = logging.getLogger(__name__)

# Propagating further than this from the element epoch is logged; beyond the limit, refused.
WARN_AGE_DAYS = 7.0
MAX_AGE_DAYS = 30.0
# WGS-72 Earth radius, km, the unit of sgp4's semi-major axis ``Satrec.a``.
_WGS72_RADIUS_KM = 6378.135


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


def orbit_from_satrec(
    satrec: Satrec, name: str, source: str, catalog_number: str | None = None
) -> Sgp4Orbit:
    """The ``Sgp4Orbit`` of an initialised sgp4 ``Satrec``; refuses one that sgp4 could not
    initialise. catalog_number: as written in the source (default: sgp4's own)."""
    if satrec.error:
        raise SatsightError(
            f"{source}: SGP4 cannot initialise these elements (sgp4 error {satrec.error}); "
            "check the mean motion and eccentricity"
        )
    satellite = EarthSatellite.from_satrec(satrec, timescale())
    satellite.name = name
    number = catalog_number or str(getattr(satrec, "satnum_str", "") or satrec.satnum)
    return Sgp4Orbit(name=name, catalog_number=number, source=source, satellite=satellite)
