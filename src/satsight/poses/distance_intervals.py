"""Distance intervals: the bands of camera-to-target range that frames are drawn in and
named by.

The paper (*An Enhanced Method for Optical Imaging Computation of Space Objects Integrating
an Improved Phong Model and Higher-Order Spherical Harmonics*, Remote Sensing, 2025) shares
its RSSF frames evenly between the approach intervals :data:`APPROACH_INTERVALS_KM` plus a
hover at :data:`HOVER_DISTANCE_KM`. Every planned frame is labelled with the interval that
holds its range (:func:`interval_name_for_range`); RSSF draws its ranges inside an interval
with :func:`sample_ranges_m`.

Units are SI (m) except where a name says otherwise (``_km``). Randomness comes only from
the ``np.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from satsight.errors import SatsightError
from satsight.poses.sampler_arguments import check_count, check_finite, check_generator

APPROACH_INTERVALS_KM: tuple[tuple[float, float], ...] = (
    (50, 40),
    (40, 30),
    (30, 20),
    (20, 10),
    (10, 5),
    (5, 0.5),
)
"""The paper's approach distance intervals as (far, near) pairs in km, far edge first."""

HOVER_DISTANCE_KM = 100.0
"""The paper's hover range (camera to target) in km."""

HOVER_RELATIVE_TOLERANCE = 0.01
"""A range within this fraction of a hover distance counts as that hover (1 %)."""

# A range this close (relative) to an outer edge of the bands counts as on it.
EDGE_RELATIVE_TOLERANCE = 1e-9

OUTSIDE_INTERVAL_NAME = "outside"
"""What :func:`interval_name_for_range` returns for a range that no interval holds."""

RangeDistribution = Literal["uniform", "log_uniform"]
RANGE_DISTRIBUTIONS: tuple[str, ...] = ("uniform", "log_uniform")


def check_distribution(distribution: object) -> str:
    if distribution not in RANGE_DISTRIBUTIONS:
        raise SatsightError(
            f"range distribution must be one of {', '.join(RANGE_DISTRIBUTIONS)}; "
            f"got {distribution!r}"
        )
    return str(distribution)


def _format_km(distance_m: float) -> str:
    return f"{distance_m / 1000.0:g}"


@dataclass(frozen=True)
class DistanceInterval:
    """A band of camera-to-target ranges from which RSSF draws its distances.

    far_m, near_m: the far and near edges of the band, metres, ``far_m >= near_m > 0``.
    ``far_m == near_m`` makes a hover: the camera holds that one range.
    name: label written with each frame; left empty it becomes ``"50-40 km"`` (far-near,
    km) or ``"hover 100 km"``.

    An approach band holds the half-open range ``[near_m, far_m)``; a hover holds the ranges
    within :data:`HOVER_RELATIVE_TOLERANCE` of its distance. :func:`interval_name_for_range`
    adds the far edges that no band of a set holds (see there).
    """

    far_m: float
    near_m: float
    name: str = ""

    def __post_init__(self) -> None:
        far = check_finite(self.far_m, "far edge of a distance interval (m)")
        near = check_finite(self.near_m, "near edge of a distance interval (m)")
        if not near > 0:
            raise SatsightError(
                f"a distance interval needs a positive near edge (the camera cannot sit at "
                f"the target), got near_m={near} m"
            )
        if far < near:
            raise SatsightError(
                f"a distance interval is given far edge first: far_m >= near_m, got "
                f"far_m={far} m, near_m={near} m; swap them"
            )
        object.__setattr__(self, "far_m", far)
        object.__setattr__(self, "near_m", near)
        if not isinstance(self.name, str):
            raise SatsightError(f"interval name must be a string, got {self.name!r}")
        if not self.name:
            name = (
                f"hover {_format_km(far)} km"
                if far == near
                else f"{_format_km(far)}-{_format_km(near)} km"
            )
            object.__setattr__(self, "name", name)

    @classmethod
    def from_km(cls, far_km: float, near_km: float, name: str = "") -> DistanceInterval:
        """The interval with edges given in km (far first)."""
        return cls(1000.0 * float(far_km), 1000.0 * float(near_km), name)

    @classmethod
    def hover(cls, distance_km: float, name: str = "") -> DistanceInterval:
        """A hover at ``distance_km`` (far == near)."""
        return cls.from_km(distance_km, distance_km, name)

    @property
    def is_hover(self) -> bool:
        """True when the interval is a single range (far == near)."""
        return self.far_m == self.near_m

    def contains(self, range_m: float) -> bool:
        """Whether ``range_m`` (m) lies in ``[near_m, far_m)``, or within 1 % of a hover."""
        r = float(range_m)
        if self.is_hover:
            return abs(r - self.far_m) <= HOVER_RELATIVE_TOLERANCE * self.far_m
        return self.near_m <= r < self.far_m


def default_intervals(include_hover: bool = True) -> tuple[DistanceInterval, ...]:
    """The paper's distance intervals: the six approach bands far first, then the hover.

    The hover comes last so that the approach bands keep the indices 0..5 of
    :data:`APPROACH_INTERVALS_KM` with or without it.
    """
    bands = tuple(DistanceInterval.from_km(far, near) for far, near in APPROACH_INTERVALS_KM)
    if include_hover:
        return (*bands, DistanceInterval.hover(HOVER_DISTANCE_KM))
    return bands


def check_intervals(intervals: object) -> tuple[DistanceInterval, ...]:
    if isinstance(intervals, DistanceInterval):
        return (intervals,)
    try:
        result = tuple(intervals)  # type: ignore[arg-type]
    except TypeError:
        raise SatsightError(
            f"expected a sequence of DistanceInterval, got {type(intervals).__name__}"
        ) from None
    if not result:
        raise SatsightError(
            "expected at least one distance interval, got none; use default_intervals()"
        )
    for item in result:
        if not isinstance(item, DistanceInterval):
            raise SatsightError(
                f"expected DistanceInterval items, got {type(item).__name__}; build them with "
                "DistanceInterval.from_km(far_km, near_km)"
            )
    names = [item.name for item in result]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise SatsightError(
            f"distance interval names must be unique, got {duplicates} more than once; "
            "give the intervals distinct names"
        )
    return result


def interval_name_for_range(
    range_m: float, intervals: Sequence[DistanceInterval] | None = None
) -> str:
    """Name of the interval that holds a camera-to-target range, or ``"outside"``.

    range_m: camera-to-target range, metres. intervals: default :func:`default_intervals`.

    Rules: an approach band holds ``[near_m, far_m)`` and a hover holds its distance within
    :data:`HOVER_RELATIVE_TOLERANCE`; where several would, the first in the given order wins.
    An edge that no interval holds that way belongs to its own band, within a relative
    :data:`EDGE_RELATIVE_TOLERANCE` (rounding in a computed range), so the union of the
    bands is covered with closed ends: with the defaults 40 km is "50-40 km", 50 km is
    "50-40 km" too, 0.5 km is "5-0.5 km", and 99.5 km is "hover 100 km". A range that no
    interval holds gives :data:`OUTSIDE_INTERVAL_NAME` (``"outside"``).
    """
    r = check_finite(range_m, "range (m)")
    checked = default_intervals() if intervals is None else check_intervals(intervals)
    for interval in checked:
        if interval.contains(r):
            return interval.name
    for interval in checked:
        if interval.is_hover:
            continue
        for edge in (interval.far_m, interval.near_m):
            if abs(r - edge) <= EDGE_RELATIVE_TOLERANCE * edge:
                return interval.name
    return OUTSIDE_INTERVAL_NAME


def interval_names_for_ranges(
    ranges_m: np.ndarray, intervals: Sequence[DistanceInterval] | None = None
) -> tuple[str, ...]:
    """:func:`interval_name_for_range` of every range in ``ranges_m`` (N,), m, at once.

    The same rules and the same float comparisons, evaluated on arrays: one pass per
    interval instead of one Python call per range, so 10^6 ranges take well under a second.
    Returns a tuple of N names (the intervals' own name strings, shared).
    """
    r = np.asarray(ranges_m, dtype=np.float64)
    if r.ndim != 1:
        raise SatsightError(f"ranges_m must be a 1-D array of ranges (m), got shape {r.shape}")
    if not np.all(np.isfinite(r)):
        bad = int(np.flatnonzero(~np.isfinite(r))[0])
        raise SatsightError(f"range (m) must be finite, got {r[bad]} at index {bad}")
    checked = default_intervals() if intervals is None else check_intervals(intervals)
    index = np.full(r.shape, len(checked), dtype=np.int64)  # len(checked): outside
    unnamed = np.ones(r.shape, dtype=bool)

    def claim(k: int, holds: np.ndarray) -> None:
        taken = unnamed & holds
        index[taken] = k
        unnamed[taken] = False

    for k, interval in enumerate(checked):
        if interval.is_hover:
            claim(k, np.abs(r - interval.far_m) <= HOVER_RELATIVE_TOLERANCE * interval.far_m)
        else:
            claim(k, (interval.near_m <= r) & (r < interval.far_m))
    for k, interval in enumerate(checked):
        if interval.is_hover:
            continue
        for edge in (interval.far_m, interval.near_m):
            claim(k, np.abs(r - edge) <= EDGE_RELATIVE_TOLERANCE * edge)
    names = [interval.name for interval in checked] + [OUTSIDE_INTERVAL_NAME]
    return tuple(names[k] for k in index.tolist())


def balanced_counts(total: int, n_bins: int) -> np.ndarray:
    """Share ``total`` frames among ``n_bins`` bins as evenly as integers allow.

    Returns (n_bins,) int64 counts summing to ``total`` that differ by at most one; the first
    ``total % n_bins`` bins get the one extra frame.
    """
    total = check_count(total, "total frame count", 0)
    n_bins = check_count(n_bins, "number of bins", 1)
    base, extra = divmod(total, n_bins)
    counts = np.full(n_bins, base, dtype=np.int64)
    counts[:extra] += 1
    return counts


def sample_ranges_m(
    interval: DistanceInterval,
    count: int,
    rng: np.random.Generator,
    distribution: RangeDistribution = "uniform",
) -> np.ndarray:
    """Draw ``count`` camera-to-target ranges (count,) in metres inside one interval.

    "uniform": uniform in range on ``[near_m, far_m)``. "log_uniform": uniform in
    ``log(range)``, so every octave (factor of two) of range gets the same share of frames
    and the median is the geometric mean ``sqrt(near_m far_m)``. Each draws ``count``
    doubles from ``rng`` (``rng.random``); a hover returns its distance and draws nothing.
    Results are kept below ``far_m`` (a rounding could reach it), so ``interval.contains``
    holds for every range.
    """
    if not isinstance(interval, DistanceInterval):
        raise SatsightError(f"expected a DistanceInterval, got {type(interval).__name__}")
    count = check_count(count, "range count", 0)
    rng = check_generator(rng)
    distribution = check_distribution(distribution)
    if interval.is_hover:
        return np.full(count, interval.far_m, dtype=np.float64)
    u = rng.random(count)
    near, far = interval.near_m, interval.far_m
    if distribution == "uniform":
        ranges = near + (far - near) * u
    else:
        log_near, log_far = math.log(near), math.log(far)
        ranges = np.exp(log_near + (log_far - log_near) * u)
    return np.clip(ranges, near, np.nextafter(far, 0.0))
