"""RSSF sampling: the Fibonacci lattice, random rotations and the RSSF bookkeeping."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from satsight.errors import SatsightError
from satsight.poses.distance_intervals import (
    DistanceInterval,
    balanced_counts,
    default_intervals,
    interval_name_for_range,
)
from satsight.poses.rssf import (
    RssfSamples,
    fibonacci_sphere,
    random_rotation_matrix,
    rssf_directions,
    rssf_samples,
)

ATOL_UNIT = 1e-12  # unit vectors and dot products, float64
Z_BOUND = 4.0  # standard errors allowed for a sample mean (two-sided p ~ 6e-5 per check)
P_MIN = 1e-3  # KS p-value floor; the seeds are fixed, so the outcome is too
SEED = 5


# --------------------------------------------------------------------------- helpers


def _random_unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _min_nearest_neighbour_angle_rad(points: np.ndarray) -> float:
    gram = np.clip(points @ points.T, -1.0, 1.0)
    np.fill_diagonal(gram, -1.0)
    return float(np.arccos(gram.max(axis=1)).min())


def _cap_discrepancy(points: np.ndarray, centres: np.ndarray, cos_radius: np.ndarray) -> float:
    """max over caps {x: x.c > h} of |fraction of points inside - cap area / 4 pi|."""
    inside = (points @ centres.T) > cos_radius
    return float(np.abs(inside.mean(axis=0) - 0.5 * (1.0 - cos_radius)).max())


def _assert_mean_within(samples: np.ndarray, mean: float, std: float, what: str) -> None:
    se = std / math.sqrt(samples.size)
    got = float(samples.mean())
    assert abs(got - mean) < Z_BOUND * se, f"{what}: mean {got} vs {mean} (se {se})"


# --------------------------------------------------------------------------- Fibonacci


@pytest.mark.parametrize("n", [1, 2, 3, 10, 99, 500, 2001])
def test_fibonacci_sphere_unit_vectors_on_the_stated_spiral(n) -> None:
    p = fibonacci_sphere(n)
    assert p.shape == (n, 3)
    assert p.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, rtol=0, atol=ATOL_UNIT)
    i = np.arange(n)
    np.testing.assert_allclose(p[:, 2], 1.0 - (2 * i + 1) / n, rtol=0, atol=ATOL_UNIT)
    # Successive points turn by the golden angle pi (3 - sqrt 5) about z.
    if n > 2:
        azimuth = np.arctan2(p[1:-1, 1], p[1:-1, 0])
        turn = np.angle(np.exp(1j * (np.diff(azimuth))))
        expected = np.angle(np.exp(1j * math.pi * (3.0 - math.sqrt(5.0))))
        np.testing.assert_allclose(turn, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("n", [2, 3, 10, 100, 500, 1000])
def test_fibonacci_sphere_mean_vector_vanishes(n) -> None:
    # sum z_i = 0 exactly; the x, y sums of the golden spiral shrink faster than 1/n
    # (measured |mean| 3.4e-5 at n = 500).
    assert np.linalg.norm(fibonacci_sphere(n).mean(axis=0)) < 1.0 / n


def test_fibonacci_sphere_is_more_even_than_random_points() -> None:
    n = 500
    lattice = fibonacci_sphere(n)
    rng = np.random.default_rng(20250)
    randoms = [_random_unit_vectors(rng, n) for _ in range(5)]

    # (a) Smallest nearest-neighbour angle: the lattice has no clumps (measured 0.138 rad
    # against a median of 0.0075 rad for five random sets).
    nn_lattice = _min_nearest_neighbour_angle_rad(lattice)
    nn_random = float(np.median([_min_nearest_neighbour_angle_rad(r) for r in randoms]))
    assert nn_lattice / nn_random > 3.0, (nn_lattice, nn_random)

    # (b) Spherical-cap discrepancy over 4000 random caps (centre uniform, cos radius
    # uniform in [-1, 1], area fraction (1 - h) / 2): measured 0.011 against a median of
    # 0.050; i.i.d. points deviate by about 1 / sqrt(n) = 0.045.
    cap_rng = np.random.default_rng(7)
    centres = _random_unit_vectors(cap_rng, 4000)
    cos_radius = cap_rng.uniform(-1.0, 1.0, 4000)
    d_lattice = _cap_discrepancy(lattice, centres, cos_radius)
    d_random = [_cap_discrepancy(r, centres, cos_radius) for r in randoms]
    assert d_lattice < min(d_random), (d_lattice, d_random)
    assert d_lattice < 0.5 * float(np.median(d_random)), (d_lattice, d_random)


@pytest.mark.parametrize("bad", [0, -3, 2.5, "10", None, True])
def test_fibonacci_sphere_rejects_bad_counts(bad) -> None:
    with pytest.raises(SatsightError, match="number of lattice points"):
        fibonacci_sphere(bad)


def test_fibonacci_sphere_accepts_numpy_integers() -> None:
    np.testing.assert_array_equal(fibonacci_sphere(np.int64(7)), fibonacci_sphere(7))


# --------------------------------------------------------------------------- rotations


def test_random_rotation_is_a_proper_rotation() -> None:
    rng = np.random.default_rng(SEED)
    for _ in range(50):
        r = random_rotation_matrix(rng)
        assert r.shape == (3, 3)
        np.testing.assert_allclose(r @ r.T, np.eye(3), rtol=0, atol=ATOL_UNIT)
        assert abs(np.linalg.det(r) - 1.0) < ATOL_UNIT


def test_random_rotation_is_uniform_on_so3() -> None:
    # Haar measure on SO(3): the rotation angle theta has the cdf (theta - sin theta) / pi,
    # the trace 1 + 2 cos theta has mean 0 and variance 1, and R e_z is uniform on the
    # sphere (each component mean 0, variance 1/3).
    n = 4000
    rng = np.random.default_rng(11)
    rotations = np.stack([random_rotation_matrix(rng) for _ in range(n)])
    trace = np.trace(rotations, axis1=1, axis2=2)
    _assert_mean_within(trace, 0.0, 1.0, "trace")
    angle = np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))
    ks = stats.kstest(angle, lambda t: (t - np.sin(t)) / math.pi)
    assert ks.pvalue > P_MIN, ks
    image_of_z = rotations[:, :, 2]
    for k in range(3):
        _assert_mean_within(image_of_z[:, k], 0.0, math.sqrt(1.0 / 3.0), f"(R e_z)[{k}]")


def test_random_rotation_draws_from_the_given_generator_only() -> None:
    a = random_rotation_matrix(np.random.default_rng(3))
    b = random_rotation_matrix(np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(SatsightError, match="Generator"):
        random_rotation_matrix(3)
    with pytest.raises(SatsightError, match="Generator"):
        random_rotation_matrix(np.random.RandomState(3))


def test_rssf_directions_are_a_rigid_rotation_of_the_lattice() -> None:
    n = 200
    lattice = fibonacci_sphere(n)
    d = rssf_directions(n, np.random.default_rng(SEED))
    assert d.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=ATOL_UNIT)
    np.testing.assert_allclose(d @ d.T, lattice @ lattice.T, rtol=0, atol=ATOL_UNIT)
    # Orientation kept too (no reflection): triple products unchanged.
    idx = np.random.default_rng(1).integers(0, n, size=(100, 3))
    np.testing.assert_allclose(
        np.linalg.det(d[idx]), np.linalg.det(lattice[idx]), rtol=0, atol=ATOL_UNIT
    )
    # The rotation is not the identity.
    assert np.abs(d - lattice).max() > 0.1


def test_rssf_directions_same_seed_same_rotation_other_seed_other() -> None:
    a = rssf_directions(64, np.random.default_rng(SEED))
    b = rssf_directions(64, np.random.default_rng(SEED))
    c = rssf_directions(64, np.random.default_rng(SEED + 1))
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.1


# --------------------------------------------------------------------------- RSSF


def test_rssf_samples_structure_and_bookkeeping() -> None:
    intervals = default_intervals()
    total = 1000
    s = rssf_samples(total, intervals, np.random.default_rng(SEED))
    assert isinstance(s, RssfSamples)
    assert len(s) == total
    assert s.direction.shape == (total, 3) and s.direction.dtype == np.float64
    assert s.range_m.shape == s.roll_rad.shape == s.interval_index.shape == (total,)
    assert len(s.interval) == total
    np.testing.assert_allclose(np.linalg.norm(s.direction, axis=1), 1.0, atol=ATOL_UNIT)
    np.testing.assert_allclose(s.offset_m, s.direction * s.range_m[:, None], rtol=0, atol=0)

    counts = np.bincount(s.interval_index, minlength=len(intervals))
    np.testing.assert_array_equal(counts, balanced_counts(total, len(intervals)))
    # Interval by interval in the given order.
    assert np.all(np.diff(s.interval_index) >= 0)
    for k, interval in enumerate(intervals):
        mask = s.interval_index == k
        assert {s.interval[i] for i in np.flatnonzero(mask)} == {interval.name}
        for r in s.range_m[mask]:
            assert interval.contains(r)
            assert interval_name_for_range(r, intervals) == interval.name
        # Each interval has its own rotated lattice of its own count.
        d = s.direction[mask]
        lattice = fibonacci_sphere(int(mask.sum()))
        np.testing.assert_allclose(d @ d.T, lattice @ lattice.T, rtol=0, atol=ATOL_UNIT)
    assert np.all(s.range_m[s.interval_index == 6] == 1e5)

    # Read-only arrays.
    with pytest.raises(ValueError, match="read-only"):
        s.range_m[0] = 1.0


def test_rssf_each_interval_gets_a_different_rotation() -> None:
    # Equal counts, so equal lattices: the directions differ only by the rotations.
    two = [DistanceInterval.from_km(10, 5), DistanceInterval.from_km(5, 1)]
    s = rssf_samples(100, two, np.random.default_rng(SEED))
    assert np.abs(s.direction[:50] - s.direction[50:]).max() > 0.1


def test_rssf_rolls_are_uniform_on_minus_pi_to_pi() -> None:
    n = 20000
    s = rssf_samples(n, default_intervals(), np.random.default_rng(SEED))
    roll = s.roll_rad
    assert roll.min() >= -math.pi and roll.max() < math.pi
    _assert_mean_within(roll, 0.0, math.pi / math.sqrt(3.0), "roll")
    ks = stats.kstest(roll, stats.uniform(loc=-math.pi, scale=2 * math.pi).cdf)
    assert ks.pvalue > P_MIN, ks


def test_rssf_directions_of_each_interval_cover_the_sphere() -> None:
    s = rssf_samples(700, default_intervals(), np.random.default_rng(SEED))
    for k in range(7):
        d = s.direction[s.interval_index == k]
        # 100 lattice points: |mean| < 1 / n stays under any rotation.
        assert np.linalg.norm(d.mean(axis=0)) < 1.0 / len(d)


def test_rssf_same_seed_same_frames_other_seed_other() -> None:
    intervals = default_intervals()
    a = rssf_samples(300, intervals, np.random.default_rng(SEED), "log_uniform")
    b = rssf_samples(300, intervals, np.random.default_rng(SEED), "log_uniform")
    c = rssf_samples(300, intervals, np.random.default_rng(SEED + 1), "log_uniform")
    for name in ("direction", "range_m", "roll_rad", "interval_index"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.interval == b.interval
    assert not np.array_equal(a.direction, c.direction)
    assert not np.array_equal(a.roll_rad, c.roll_rad)
    assert not np.array_equal(a.range_m, c.range_m)


def test_rssf_distribution_changes_only_the_ranges() -> None:
    intervals = default_intervals()
    u = rssf_samples(300, intervals, np.random.default_rng(SEED), "uniform")
    g = rssf_samples(300, intervals, np.random.default_rng(SEED), "log_uniform")
    np.testing.assert_array_equal(u.direction, g.direction)
    np.testing.assert_array_equal(u.roll_rad, g.roll_rad)
    np.testing.assert_array_equal(u.interval_index, g.interval_index)
    approach = u.interval_index < 6
    assert np.all(u.range_m[approach] != g.range_m[approach])


def test_rssf_zero_frames_and_errors() -> None:
    s = rssf_samples(0, default_intervals(), np.random.default_rng(SEED))
    assert len(s) == 0 and s.direction.shape == (0, 3)
    few = rssf_samples(3, default_intervals(), np.random.default_rng(SEED))
    assert few.interval == ("50-40 km", "40-30 km", "30-20 km")
    with pytest.raises(SatsightError, match="Generator"):
        rssf_samples(10, default_intervals(), SEED)
    with pytest.raises(SatsightError, match="at least one"):
        rssf_samples(10, [], np.random.default_rng(SEED))
    with pytest.raises(SatsightError, match="unique"):
        rssf_samples(10, [DistanceInterval.hover(1)] * 2, np.random.default_rng(SEED))
    with pytest.raises(SatsightError, match="distribution"):
        rssf_samples(10, default_intervals(), np.random.default_rng(SEED), "normal")
    with pytest.raises(SatsightError, match="total frame count"):
        rssf_samples(-1, default_intervals(), np.random.default_rng(SEED))
