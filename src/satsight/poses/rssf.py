"""RSSF, "random sampling based on the spherical Fibonacci function": random viewing
geometries about the target.

The sampler of the paper (*An Enhanced Method for Optical Imaging Computation of Space
Objects Integrating an Improved Phong Model and Higher-Order Spherical Harmonics*, Remote
Sensing, 2025), as pure sampling math; turning the samples into camera poses is done
elsewhere. Viewing directions lie on a spherical Fibonacci lattice turned by a uniformly
random rotation, with a uniformly random roll about the boresight, and a camera-to-target
range drawn inside one of a set of distance intervals (``satsight.poses.distance_intervals``)
with the frames shared out evenly between the intervals (:func:`rssf_samples`). The paper
seeds its generator with 5 (``np.random.default_rng(5)`` here gives satsight's own
reproducible draws, not the paper's).

Units are SI (m, rad). Vectors carry their components on the last axis, float64.
Randomness comes only from the ``np.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.quaternion import matrix_from_quaternion
from satsight.poses.distance_intervals import (
    DistanceInterval,
    RangeDistribution,
    balanced_counts,
    check_distribution,
    check_intervals,
    sample_ranges_m,
)
from satsight.poses.sampler_arguments import check_count, check_generator

_GOLDEN_ANGLE_RAD = math.pi * (3.0 - math.sqrt(5.0))  # 2 pi / phi^2, about 137.5 deg


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
    n = check_count(n, "number of lattice points", 1)
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
    rng = check_generator(rng)
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
    n = check_count(n, "number of directions", 1)
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
    total_frames = check_count(total_frames, "total frame count", 0)
    checked = check_intervals(intervals)
    rng = check_generator(rng)
    distribution = check_distribution(distribution)
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
