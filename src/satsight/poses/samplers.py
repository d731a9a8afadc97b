"""Viewpoint sampling: frame times along a trajectory and random viewing geometries.

The two samplers of the paper (*An Enhanced Method for Optical Imaging Computation of Space
Objects Integrating an Improved Phong Model and Higher-Order Spherical Harmonics*, Remote
Sensing, 2025), as pure sampling math; turning the samples into camera poses is done
elsewhere.

SSPT, "sequential frames along a predefined trajectory": frame times at uniform intervals
along a trajectory segment (:func:`sspt_times_s`), or at uniform steps of the phase angle of
a periodic motion such as a fly-around (:func:`sspt_angle_times_s`).

RSSF, "random sampling based on the spherical Fibonacci function": viewing directions on a
spherical Fibonacci lattice turned by a uniformly random rotation, a uniformly random roll
about the boresight, and a camera-to-target range drawn inside one of a set of distance
intervals with the frames shared out evenly between the intervals (:func:`rssf_samples`).
The paper's intervals are :data:`APPROACH_INTERVALS_KM` plus a hover at
:data:`HOVER_DISTANCE_KM`; it seeds its generator with 5 (``np.random.default_rng(5)``
here gives satsight's own reproducible draws, not the paper's).

Units are SI (m, s, rad) except where a name says otherwise (``_km``, ``_deg``). Vectors
carry their components on the last axis, float64. Randomness comes only from the
``np.random.Generator`` passed in.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion

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
# A range this close (relative) to an outer edge of the bands counts as on it.
EDGE_RELATIVE_TOLERANCE = 1e-9
"""A range within this fraction of a hover distance counts as that hover (1 %)."""

OUTSIDE_INTERVAL_NAME = "outside"
"""What :func:`interval_name_for_range` returns for a range that no interval holds."""

SSPT_TIME_TOLERANCE_S = 1e-9
"""A time grid point within this many seconds of the segment end counts as the end."""

ANGLE_TOLERANCE_STEPS = 1e-9
"""An angle grid point within this fraction of a step of the stop angle counts as the stop."""

RangeDistribution = Literal["uniform", "log_uniform"]
RANGE_DISTRIBUTIONS: tuple[str, ...] = ("uniform", "log_uniform")

_GOLDEN_ANGLE_RAD = math.pi * (3.0 - math.sqrt(5.0))  # 2 pi / phi^2, about 137.5 deg


# --------------------------------------------------------------------------- checks


def _check_generator(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise SatsightError(
            f"expected a numpy random Generator, got {type(rng).__name__}; "
            "pass one explicitly, e.g. rng=np.random.default_rng(5)"
        )
    return rng


def _check_count(value: object, what: str, minimum: int) -> int:
    if isinstance(value, bool):
        raise SatsightError(f"{what} must be an integer >= {minimum}, got the boolean {value}")
    try:
        count = operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise SatsightError(
            f"{what} must be an integer >= {minimum}, got {value!r} "
            f"({type(value).__name__}); pass a whole number"
        ) from None
    if count < minimum:
        raise SatsightError(f"{what} must be an integer >= {minimum}, got {count}")
    return count


def _check_finite(value: object, what: str) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise SatsightError(f"{what} must be a real number, got {value!r}") from None
    if not math.isfinite(number):
        raise SatsightError(f"{what} must be finite, got {number}")
    return number


def _check_distribution(distribution: object) -> str:
    if distribution not in RANGE_DISTRIBUTIONS:
        raise SatsightError(
            f"range distribution must be one of {', '.join(RANGE_DISTRIBUTIONS)}; "
            f"got {distribution!r}"
        )
    return str(distribution)


# --------------------------------------------------------------------------- intervals


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
        far = _check_finite(self.far_m, "far edge of a distance interval (m)")
        near = _check_finite(self.near_m, "near edge of a distance interval (m)")
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


def _check_intervals(intervals: object) -> tuple[DistanceInterval, ...]:
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
    r = _check_finite(range_m, "range (m)")
    checked = default_intervals() if intervals is None else _check_intervals(intervals)
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
    checked = default_intervals() if intervals is None else _check_intervals(intervals)
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
    total = _check_count(total, "total frame count", 0)
    n_bins = _check_count(n_bins, "number of bins", 1)
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
    count = _check_count(count, "range count", 0)
    rng = _check_generator(rng)
    distribution = _check_distribution(distribution)
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


# --------------------------------------------------------------------------- directions


def fibonacci_sphere(n: int) -> np.ndarray:
    """Unit vectors (n, 3) of the spherical Fibonacci lattice with ``n`` points.

    Point i (0-based) sits at ``z_i = 1 - (2 i + 1) / n`` and azimuth
    ``phi_i = i pi (3 - sqrt 5)`` (the golden angle), ``x + i y = sqrt(1 - z^2) e^{i phi}``:
    equal-area bands in z, each holding one point, turned by the golden angle so that the
    points spread nearly uniformly over the sphere (González 2010, "Measurement of areas on
    a sphere using Fibonacci and latitude-longitude lattices", Math. Geosci. 42, 49-64;
    Keinert et al. 2015, "Spherical Fibonacci Mapping", ACM Trans. Graph. 34(6), 193).
    Unitless directions in whatever frame the caller gives them.
    """
    n = _check_count(n, "number of lattice points", 1)
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    radius = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    phi = _GOLDEN_ANGLE_RAD * i
    return np.stack([radius * np.cos(phi), radius * np.sin(phi), z], axis=-1)


def random_rotation_matrix(rng: np.random.Generator) -> np.ndarray:
    """A rotation matrix (3, 3) drawn uniformly (Haar measure) from SO(3).

    Four standard normal draws from ``rng``, normalised, give a unit quaternion uniform on
    the 3-sphere (Muller 1959, "A note on a method for generating points uniformly on
    n-dimensional spheres", Commun. ACM 2(4)); since q and -q are the same rotation, the
    matrix is uniform on SO(3) (Shoemake 1992, "Uniform random rotations", Graphics Gems
    III, 124-132). Draws exactly four doubles per call (more only in the probability-zero
    case of a vanishing quaternion).
    """
    rng = _check_generator(rng)
    while True:
        q = rng.standard_normal(4)
        norm = float(np.linalg.norm(q))
        if norm > 1e-6:
            return matrix_from_quaternion(q / norm)


def rssf_directions(n: int, rng: np.random.Generator) -> np.ndarray:
    """The ``n``-point spherical Fibonacci lattice (n, 3) turned by one random rotation.

    Row i is ``R @ fibonacci_sphere(n)[i]`` with ``R = random_rotation_matrix(rng)``: the
    rotation keeps the lattice's even spread and removes its fixed poles and seam, so
    different generators give differently placed but equally uniform viewing directions.
    Draws four doubles from ``rng``.
    """
    n = _check_count(n, "number of directions", 1)
    rotation = random_rotation_matrix(rng)
    return fibonacci_sphere(n) @ rotation.T


@dataclass(frozen=True)
class RssfSamples:
    """RSSF viewing geometry of N frames (arrays are read-only).

    direction: (N, 3) unit vectors from the target centre towards the camera, in the frame
    the caller chose for the lattice (the target body frame in practice).
    range_m: (N,) camera-to-target-centre range, metres.
    roll_rad: (N,) roll of the camera about its boresight, radians, in ``[-pi, pi)``.
    interval: (N,) name of the distance interval of each frame.
    interval_index: (N,) int64 index of that interval in the intervals given.
    """

    direction: np.ndarray
    range_m: np.ndarray
    roll_rad: np.ndarray
    interval: tuple[str, ...]
    interval_index: np.ndarray

    def __post_init__(self) -> None:
        direction = np.array(self.direction, dtype=np.float64)
        range_m = np.array(self.range_m, dtype=np.float64)
        roll_rad = np.array(self.roll_rad, dtype=np.float64)
        interval_index = np.array(self.interval_index, dtype=np.int64)
        interval = tuple(str(name) for name in self.interval)
        n = range_m.shape[0] if range_m.ndim == 1 else -1
        if (
            n < 0
            or direction.shape != (n, 3)
            or roll_rad.shape != (n,)
            or interval_index.shape != (n,)
            or len(interval) != n
        ):
            raise SatsightError(
                "RSSF samples need direction (N, 3) and range_m, roll_rad, interval, "
                f"interval_index of length N; got shapes {direction.shape}, {range_m.shape}, "
                f"{roll_rad.shape}, ({len(interval)},), {interval_index.shape}"
            )
        for name, array in (
            ("direction", direction),
            ("range_m", range_m),
            ("roll_rad", roll_rad),
            ("interval_index", interval_index),
        ):
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        object.__setattr__(self, "interval", interval)

    def __len__(self) -> int:
        return int(self.range_m.shape[0])

    @property
    def offset_m(self) -> np.ndarray:
        """(N, 3) camera position relative to the target centre, metres: direction * range."""
        return self.direction * self.range_m[:, None]


def rssf_samples(
    total_frames: int,
    intervals: Sequence[DistanceInterval],
    rng: np.random.Generator,
    distribution: RangeDistribution = "uniform",
) -> RssfSamples:
    """Directions, ranges and rolls of ``total_frames`` RSSF frames.

    Counts: interval k gets ``balanced_counts(total_frames, len(intervals))[k]`` frames, and
    its frames look along its own spherical Fibonacci lattice of that many points, turned by
    its own random rotation, so every interval covers the whole sphere evenly.
    Frame order: interval by interval in the order given, each in lattice order.
    Ranges: :func:`sample_ranges_m` with ``distribution``. Rolls: uniform on ``[-pi, pi)``.

    Draw order from ``rng``: first one rotation per interval in order (four normal draws
    each, drawn even for an interval with no frames), then one roll per frame (N uniform
    doubles), then the ranges interval by interval (one double per frame, none for a
    hover). Directions and rolls therefore do not depend on ``distribution``, and the same
    generator state gives identical arrays.
    """
    total_frames = _check_count(total_frames, "total frame count", 0)
    checked = _check_intervals(intervals)
    rng = _check_generator(rng)
    distribution = _check_distribution(distribution)
    counts = balanced_counts(total_frames, len(checked))

    rotations = [random_rotation_matrix(rng) for _ in checked]
    roll_rad = 2.0 * math.pi * (rng.random(total_frames) - 0.5)  # u - 0.5 is exact
    roll_rad = np.where(roll_rad >= math.pi, -math.pi, roll_rad)  # guard the open end
    ranges = [
        sample_ranges_m(interval, int(count), rng, distribution)
        for interval, count in zip(checked, counts, strict=True)
    ]
    directions = [
        fibonacci_sphere(int(count)) @ rotation.T if count > 0 else np.zeros((0, 3))
        for rotation, count in zip(rotations, counts, strict=True)
    ]
    interval_index = np.repeat(np.arange(len(checked), dtype=np.int64), counts)
    return RssfSamples(
        direction=np.concatenate(directions, axis=0),
        range_m=np.concatenate(ranges),
        roll_rad=roll_rad,
        interval=tuple(checked[k].name for k in interval_index),
        interval_index=interval_index,
    )


# --------------------------------------------------------------------------- SSPT


def sspt_times_s(
    start_s: float,
    end_s: float,
    frame_count: int | None = None,
    step_s: float | None = None,
    include_end: bool = True,
) -> np.ndarray:
    """Frame times (N,) in seconds along the trajectory segment from ``start_s`` to ``end_s``.

    Give exactly one of:

    frame_count: N frames evenly spaced. With ``include_end`` they run from start to end
    inclusive (``np.linspace``; N == 1 gives ``[start_s]``); without, they divide
    ``[start_s, end_s)`` into N equal steps (a closed orbit then has no repeated frame).
    step_s: one frame every ``step_s`` seconds, ``start_s + k step_s``, while the time does
    not pass ``end_s`` (a grid point within :data:`SSPT_TIME_TOLERANCE_S` of the end counts
    as the end). The end itself is a frame only when it lands on that grid and
    ``include_end`` is set.

    Times are on the caller's time axis (e.g. seconds from the scenario epoch).
    """
    start = _check_finite(start_s, "segment start time (s)")
    end = _check_finite(end_s, "segment end time (s)")
    if end < start:
        raise SatsightError(
            f"segment end must not precede its start, got start_s={start} s, end_s={end} s"
        )
    if (frame_count is None) == (step_s is None):
        raise SatsightError(
            "give exactly one of frame_count (N evenly spaced frames) or step_s (one frame "
            f"every step_s seconds); got frame_count={frame_count!r}, step_s={step_s!r}"
        )
    if frame_count is not None:
        n = _check_count(frame_count, "frame_count", 1)
        if n > 1 and end == start:
            raise SatsightError(
                f"{n} frames on a segment of zero length would share one time ({start} s); "
                "give end_s > start_s or frame_count=1"
            )
        if include_end:
            return np.linspace(start, end, n)
        return start + (end - start) * (np.arange(n, dtype=np.float64) / n)
    step = _check_finite(step_s, "step_s")
    if not step > 0:
        raise SatsightError(f"step_s must be positive, got {step} s")
    k_last = math.floor((end - start + SSPT_TIME_TOLERANCE_S) / step)
    times = start + step * np.arange(k_last + 1, dtype=np.float64)
    if not include_end:
        times = times[times < end - SSPT_TIME_TOLERANCE_S]
    if times.size == 0:
        raise SatsightError(
            f"no frame time lies in [{start}, {end}) s without the end; give end_s > "
            "start_s or include_end=True"
        )
    return times


def sspt_angle_times_s(
    period_s: float,
    start_deg: float,
    stop_deg: float,
    step_deg: float,
    start_s: float = 0.0,
    include_stop: bool = False,
) -> np.ndarray:
    """Frame times (N,) in seconds of a uniform periodic motion at evenly stepped angles.

    The motion (e.g. a fly-around) turns 360 deg every ``period_s`` seconds and is at phase
    angle 0 deg at time ``start_s``, so angle ``a`` is reached at
    ``start_s + period_s a / 360``. Frames sit at ``start_deg, start_deg + step_deg, ...``
    while below ``stop_deg``; with ``include_stop`` the stop angle is a frame too when it
    lands on that grid (within :data:`ANGLE_TOLERANCE_STEPS` of a step).

    Default ``include_stop=False``: the paper's "0 deg to 360 deg at 5 deg per frame" gives
    72 distinct views at ``k period_s / 72``, since 0 deg and 360 deg are the same view;
    ``include_stop=True`` gives 73 frames, the last repeating the first.
    """
    period = _check_finite(period_s, "period_s")
    start = _check_finite(start_deg, "start_deg")
    stop = _check_finite(stop_deg, "stop_deg")
    step = _check_finite(step_deg, "step_deg")
    t0 = _check_finite(start_s, "start_s")
    if not period > 0:
        raise SatsightError(f"period_s must be positive, got {period} s")
    if not step > 0:
        raise SatsightError(f"step_deg must be positive, got {step} deg")
    if stop < start:
        raise SatsightError(
            f"stop angle must not precede the start angle, got start_deg={start}, "
            f"stop_deg={stop}; angles grow with time"
        )
    k = np.arange(math.floor((stop - start) / step + ANGLE_TOLERANCE_STEPS) + 1)
    angles_deg = start + step * k.astype(np.float64)
    if not include_stop:
        angles_deg = angles_deg[angles_deg < stop - ANGLE_TOLERANCE_STEPS * step]
    if angles_deg.size == 0:
        raise SatsightError(
            f"no angle lies in [{start}, {stop}) deg; give stop_deg > start_deg or "
            "include_stop=True"
        )
    return t0 + period * (angles_deg / 360.0)
