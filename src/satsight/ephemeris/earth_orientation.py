"""The Earth's orientation in GCRS: the rotation to the Earth-fixed frame and the pole.

Frames: GCRS (the inertial frame of :mod:`satsight.ephemeris.orbits`) and ITRS (the
International Terrestrial Reference System, the Earth-fixed frame whose z axis is the
Earth's reference pole, to which the zonal gravity coefficients J2, J3, ... refer).

The rotation comes from skyfield (``skyfield.framelib.itrs``, offline):
``R_itrs_from_gcrs = W R3(-GAST) N P B``, with the frame bias B, the IAU 2006 precession P,
the full IAU 2000A nutation N, Greenwich apparent sidereal time (from UT1, i.e. from
skyfield's built-in Delta T table) and the polar-motion matrix W. The IERS Conventions
(2010, Technical Note 36, Ch. 5) define the same chain; skyfield's equinox-based form
agrees with the CIO-based one to well below a milliarcsecond in the pole direction.

**Polar motion is absent**: with the built-in timescale (no IERS ``finals`` file is loaded,
and nothing is downloaded) skyfield sets W = I, so the ITRS z axis computed here is the
Celestial Intermediate Pole (CIP). The true ITRS pole differs from it by the polar
motion (x_p, y_p), a wobble of 0.2-0.6 arcsec (Chandler and annual terms; IERS EOP C04).
For zonal gravity this tilts the symmetry axis by up to 3e-6 rad: measured for a 7000 km,
51.6 deg LEO, a 0.5 arcsec tilt of the pole moves the position after one orbit by 0.1-0.5
m (1.5-7.5 m after a day) depending on its direction, against ~430 m per orbit for the
2.4e-3 rad precession-nutation offset at 2025 (:mod:`satsight.ephemeris.propagation`), and
is smaller than the neglected J3 (80 m per orbit) and tesseral terms (C22, S22 are as large
as J3).

**Pole interpolation.** Zonal gravity needs only the pole, which moves slowly in GCRS:
precession carries it about 20 arcsec per year, and nutation adds periodic terms of up to
9.2 arcsec (18.6 yr), 0.57 arcsec (half a year) and 0.09 arcsec (13.7 days); measured, it
moves 3.8e-7 rad (0.08 arcsec) in a day. :class:`PoleTrack` evaluates the pole with
skyfield on a grid of nodes every ``POLE_NODE_SPACING_S`` (1 hour) and interpolates
linearly between them, so an integrator can ask for the pole at every stage time for a few
float operations. Linear interpolation's error is bounded by ``h^2 / 8`` times the pole's
angular acceleration; measured against direct evaluation every 60 s over 30 days from
2025-03-20: at most 4e-11 rad (8e-6 arcsec). Scaled by the orbit's sensitivity to the axis
(about 2e5 m per rad after one LEO orbit, from the figures above) that is below 1e-5 m per
orbit. The chord is not renormalised: its norm is 1 to within 5e-16.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from skyfield.framelib import itrs
from skyfield.timelib import Time

from satsight.ephemeris.time import SECONDS_PER_DAY, parse_epoch_utc, timescale
from satsight.errors import SatsightError

# Spacing of the pole's interpolation nodes, s (see the module docstring for its error).
POLE_NODE_SPACING_S = 3600.0


def as_time(epoch: Time | str) -> Time:
    """A scalar skyfield ``Time`` from a ``Time`` or a UTC ISO-8601 string.

    Strings are parsed by :func:`satsight.ephemeris.time.parse_epoch_utc`.
    """
    if isinstance(epoch, str):
        return parse_epoch_utc(epoch)
    if isinstance(epoch, Time):
        if np.ndim(epoch.tt) != 0:
            raise SatsightError(
                f"epoch must be a scalar skyfield Time; got one of shape {np.shape(epoch.tt)}"
            )
        return epoch
    raise SatsightError(
        "epoch must be a skyfield Time or a UTC ISO-8601 string such as "
        f"'2025-03-20T12:00:00Z'; got {type(epoch).__name__}"
    )


def times_after(epoch: Time | str, offsets_s: object) -> Time:
    """(N,) skyfield ``Time``: ``epoch`` plus offsets_s (N,) elapsed (TT) seconds.

    The offsets are split into whole days and a remainder, as in
    :func:`satsight.ephemeris.time.epoch_times`, so precision is kept over long spans.
    """
    t0 = as_time(epoch)
    offsets = np.atleast_1d(np.asarray(offsets_s, dtype=np.float64))
    if offsets.ndim != 1 or not np.all(np.isfinite(offsets)):
        raise SatsightError(
            f"offsets_s must be a finite scalar or 1-D array of seconds; got shape "
            f"{np.shape(offsets_s)}"
        )
    days = np.floor(offsets / SECONDS_PER_DAY)
    rest_days = (offsets - days * SECONDS_PER_DAY) / SECONDS_PER_DAY
    return timescale().tt_jd(float(t0.whole) + days, float(t0.tt_fraction) + rest_days)


def R_itrs_from_gcrs(times: Time) -> np.ndarray:
    """(N, 3, 3) rotation with ``x_itrs = R @ x_gcrs`` at skyfield ``times`` (scalar: N = 1).

    Precession, nutation and Earth rotation from skyfield; no polar motion (module
    docstring).
    """
    R = np.asarray(itrs.rotation_at(times), dtype=np.float64)
    if R.ndim == 2:
        R = R[:, :, None]
    return np.moveaxis(R, -1, 0).copy()


def R_gcrs_from_itrs(times: Time) -> np.ndarray:
    """(N, 3, 3) rotation with ``x_gcrs = R @ x_itrs``: the transpose of R_itrs_from_gcrs."""
    return np.swapaxes(R_itrs_from_gcrs(times), -1, -2).copy()


def pole_gcrs(times: Time) -> np.ndarray:
    """(N, 3) unit vector of the ITRS z axis (the Earth's pole) in GCRS at ``times``.

    It is the third row of R_itrs_from_gcrs (the third column of R_gcrs_from_itrs); Earth
    rotation does not enter it.
    """
    return R_itrs_from_gcrs(times)[:, 2, :].copy()


@dataclass(frozen=True)
class PoleTrack:
    """The Earth's pole in GCRS from an epoch on, linearly interpolated between nodes.

    epoch_tt_jd: (whole, fraction) TT Julian date of t = 0. node_spacing_s: s between
    nodes. nodes_gcrs: (M, 3) unit pole vectors at t = k * node_spacing_s, k = 0..M-1.
    Times beyond the last node are extrapolated linearly from the last interval (build the
    track over the whole span to avoid it).
    """

    epoch_tt_jd: tuple[float, float]
    node_spacing_s: float
    nodes_gcrs: np.ndarray

    @property
    def span_s(self) -> float:
        """Seconds covered by the nodes, from t = 0 to the last node."""
        return (self.nodes_gcrs.shape[0] - 1) * self.node_spacing_s

    def at(self, t_s: object) -> np.ndarray:
        """(N, 3) interpolated pole in GCRS at t_s (N,), s after the epoch."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        u = t / self.node_spacing_s
        last = self.nodes_gcrs.shape[0] - 2
        k = np.clip(np.floor(u).astype(np.int64), 0, last)
        w = (u - k)[:, None]
        return (1.0 - w) * self.nodes_gcrs[k] + w * self.nodes_gcrs[k + 1]

    def scalar_function(self):
        """A fast ``pole(t_s) -> (px, py, pz)`` on Python floats, for integrator loops.

        Same interpolation as :meth:`at`; per-interval slopes are precomputed.
        """
        nodes = self.nodes_gcrs
        spacing = self.node_spacing_s
        last = nodes.shape[0] - 2
        starts = [tuple(float(c) for c in row) for row in nodes[:-1]]
        slopes = [tuple(float(c) for c in row) for row in np.diff(nodes, axis=0)]

        def pole(t_s: float) -> tuple[float, float, float]:
            u = t_s / spacing
            k = min(max(int(u), 0), last)  # int truncates: floor for u >= 0
            w = u - k
            (x0, y0, z0), (dx, dy, dz) = starts[k], slopes[k]
            return x0 + w * dx, y0 + w * dy, z0 + w * dz

        return pole


@lru_cache(maxsize=32)
def _pole_nodes(whole: float, fraction: float, count: int, spacing_s: float) -> np.ndarray:
    offsets = np.arange(count, dtype=np.float64) * spacing_s
    days = np.floor(offsets / SECONDS_PER_DAY)
    rest = (offsets - days * SECONDS_PER_DAY) / SECONDS_PER_DAY
    nodes = pole_gcrs(timescale().tt_jd(whole + days, fraction + rest))
    nodes.flags.writeable = False
    return nodes


def pole_track(
    epoch: Time | str, span_s: float, node_spacing_s: float = POLE_NODE_SPACING_S
) -> PoleTrack:
    """The pole from ``epoch`` over [0, span_s] s, nodes every node_spacing_s (cached).

    ``epoch``: scalar skyfield ``Time`` or UTC ISO-8601 string. At least two nodes are
    built, and the last lies at or after span_s.
    """
    span = float(span_s)
    spacing = float(node_spacing_s)
    if not (math.isfinite(span) and span >= 0.0):
        raise SatsightError(f"span_s must be a finite number >= 0 s; got {span_s}")
    if not (math.isfinite(spacing) and spacing > 0.0):
        raise SatsightError(f"node_spacing_s must be a finite number > 0 s; got {node_spacing_s}")
    t0 = as_time(epoch)
    count = max(2, math.ceil(span / spacing - 1e-12) + 1)
    whole, fraction = float(t0.whole), float(t0.tt_fraction)
    return PoleTrack((whole, fraction), spacing, _pole_nodes(whole, fraction, count, spacing))
