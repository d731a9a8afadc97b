"""Viewpoint samplers: Fibonacci lattice, random rotations, RSSF bookkeeping and SSPT times."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from satsight.errors import SatsightError
from satsight.poses.samplers import (
    APPROACH_INTERVALS_KM,
    HOVER_DISTANCE_KM,
    OUTSIDE_INTERVAL_NAME,
    DistanceInterval,
    RssfSamples,
    balanced_counts,
    default_intervals,
    fibonacci_sphere,
    interval_name_for_range,
    random_rotation_matrix,
    rssf_directions,
    rssf_samples,
    sample_ranges_m,
    sspt_angle_times_s,
    sspt_times_s,
)

ATOL_UNIT = 1e-12  # unit vectors and dot products, float64
RTOL_TIME = 1e-12
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


# --------------------------------------------------------------------------- intervals


def test_default_intervals_follow_the_paper() -> None:
    intervals = default_intervals()
    assert len(intervals) == 7
    assert [i.name for i in intervals] == [
        "50-40 km",
        "40-30 km",
        "30-20 km",
        "20-10 km",
        "10-5 km",
        "5-0.5 km",
        "hover 100 km",
    ]
    for interval, (far_km, near_km) in zip(intervals, APPROACH_INTERVALS_KM, strict=False):
        assert interval.far_m == 1000.0 * far_km
        assert interval.near_m == 1000.0 * near_km
        assert not interval.is_hover
    hover = intervals[-1]
    assert hover.is_hover
    assert hover.far_m == hover.near_m == HOVER_DISTANCE_KM * 1000.0
    assert default_intervals(include_hover=False) == intervals[:-1]


def test_distance_interval_validation() -> None:
    with pytest.raises(SatsightError, match="far edge first"):
        DistanceInterval(1000.0, 2000.0)
    with pytest.raises(SatsightError, match="positive near edge"):
        DistanceInterval(1000.0, 0.0)
    with pytest.raises(SatsightError, match="finite"):
        DistanceInterval(math.inf, 10.0)
    named = DistanceInterval(2000.0, 1000.0, "close")
    assert named.name == "close"
    assert DistanceInterval(2000.0, 1500.0).name == "2-1.5 km"


@pytest.mark.parametrize(
    ("range_km", "expected"),
    [
        (50.0, "50-40 km"),  # the outermost far edge belongs to the outermost band
        (45.0, "50-40 km"),
        (40.0, "50-40 km"),  # a shared edge belongs to the band it is the near edge of
        (39.999, "40-30 km"),
        (30.0, "40-30 km"),
        (25.0, "30-20 km"),
        (20.0, "30-20 km"),
        (15.0, "20-10 km"),
        (10.0, "20-10 km"),
        (7.0, "10-5 km"),
        (5.0, "10-5 km"),
        (4.999, "5-0.5 km"),
        (0.5, "5-0.5 km"),
        (50.0 * (1 + 1e-10), "50-40 km"),  # rounding in a computed range at the outer edges
        (0.5 * (1 - 1e-10), "5-0.5 km"),
        (100.0, "hover 100 km"),
        (99.5, "hover 100 km"),
        (100.9, "hover 100 km"),
        (0.4999, OUTSIDE_INTERVAL_NAME),
        (50.001, OUTSIDE_INTERVAL_NAME),
        (70.0, OUTSIDE_INTERVAL_NAME),
        (98.9, OUTSIDE_INTERVAL_NAME),
        (101.1, OUTSIDE_INTERVAL_NAME),
        (0.0, OUTSIDE_INTERVAL_NAME),
        (-10.0, OUTSIDE_INTERVAL_NAME),
    ],
)
def test_interval_name_for_range(range_km, expected) -> None:
    assert interval_name_for_range(1000.0 * range_km, default_intervals()) == expected
    assert interval_name_for_range(1000.0 * range_km) == expected


def test_interval_name_for_range_without_hover_and_bad_input() -> None:
    assert interval_name_for_range(1e5, default_intervals(False)) == OUTSIDE_INTERVAL_NAME
    with pytest.raises(SatsightError, match="finite"):
        interval_name_for_range(math.nan)
    with pytest.raises(SatsightError, match="at least one"):
        interval_name_for_range(1e4, [])


def test_contains_is_half_open_and_hover_tolerant() -> None:
    band = DistanceInterval.from_km(10, 5)
    assert band.contains(5000.0)
    assert band.contains(9999.999)
    assert not band.contains(10000.0)
    assert not band.contains(4999.999)
    hover = DistanceInterval.hover(100)
    assert hover.contains(1e5) and hover.contains(0.991e5) and hover.contains(1.009e5)
    assert not hover.contains(0.989e5) and not hover.contains(1.011e5)


@pytest.mark.parametrize("total", [0, 1, 5, 6, 7, 13, 100, 1001])
@pytest.mark.parametrize("n_bins", [1, 2, 6, 7, 10])
def test_balanced_counts(total, n_bins) -> None:
    counts = balanced_counts(total, n_bins)
    assert counts.shape == (n_bins,)
    assert np.issubdtype(counts.dtype, np.integer)
    assert counts.sum() == total
    assert counts.max() - counts.min() <= 1
    # The extra frames go to the first bins.
    assert np.all(np.diff(counts) <= 0)


def test_balanced_counts_errors() -> None:
    with pytest.raises(SatsightError, match="total frame count"):
        balanced_counts(-1, 3)
    with pytest.raises(SatsightError, match="number of bins"):
        balanced_counts(10, 0)


# --------------------------------------------------------------------------- ranges


@pytest.mark.parametrize("far_km, near_km", APPROACH_INTERVALS_KM)
def test_uniform_ranges_fill_their_interval(far_km, near_km) -> None:
    n = 20000
    interval = DistanceInterval.from_km(far_km, near_km)
    r = sample_ranges_m(interval, n, np.random.default_rng(SEED), "uniform")
    assert r.shape == (n,)
    assert r.min() >= interval.near_m and r.max() < interval.far_m
    width = interval.far_m - interval.near_m
    _assert_mean_within(r, interval.near_m + width / 2, width / math.sqrt(12.0), "range")
    ks = stats.kstest(r, stats.uniform(loc=interval.near_m, scale=width).cdf)
    assert ks.pvalue > P_MIN, ks


@pytest.mark.parametrize("far_km, near_km", APPROACH_INTERVALS_KM)
def test_log_uniform_ranges_have_the_geometric_mean_as_median(far_km, near_km) -> None:
    n = 20000
    interval = DistanceInterval.from_km(far_km, near_km)
    r = sample_ranges_m(interval, n, np.random.default_rng(SEED), "log_uniform")
    assert r.min() >= interval.near_m and r.max() < interval.far_m
    # log r is uniform on [a, b]: its sample median has standard error (b - a) / (2 sqrt n).
    a, b = math.log(interval.near_m), math.log(interval.far_m)
    se = (b - a) / (2.0 * math.sqrt(n))
    assert abs(math.log(np.median(r)) - 0.5 * (a + b)) < Z_BOUND * se
    # Equal share per octave: the fraction below 2 near is log 2 / (b - a).
    if interval.far_m > 2.0 * interval.near_m:
        p = math.log(2.0) / (b - a)
        got = float(np.mean(r < 2.0 * interval.near_m))
        assert abs(got - p) < Z_BOUND * math.sqrt(p * (1 - p) / n), (got, p)


def test_hover_ranges_are_constant_and_draw_nothing() -> None:
    rng = np.random.default_rng(SEED)
    state = rng.bit_generator.state
    r = sample_ranges_m(DistanceInterval.hover(100), 9, rng, "log_uniform")
    np.testing.assert_array_equal(r, np.full(9, 1e5))
    assert rng.bit_generator.state == state


def test_sample_ranges_errors() -> None:
    interval = DistanceInterval.from_km(10, 5)
    rng = np.random.default_rng(SEED)
    with pytest.raises(SatsightError, match="distribution"):
        sample_ranges_m(interval, 3, rng, "gaussian")
    with pytest.raises(SatsightError, match="range count"):
        sample_ranges_m(interval, -1, rng)
    with pytest.raises(SatsightError, match="DistanceInterval"):
        sample_ranges_m((10, 5), 3, rng)
    assert sample_ranges_m(interval, 0, rng).shape == (0,)


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


# --------------------------------------------------------------------------- SSPT


def test_sspt_frame_count_spans_the_segment() -> None:
    t = sspt_times_s(100.0, 200.0, frame_count=11)
    np.testing.assert_allclose(t, 100.0 + 10.0 * np.arange(11), rtol=RTOL_TIME, atol=0)
    assert t[0] == 100.0 and t[-1] == 200.0
    open_end = sspt_times_s(100.0, 200.0, frame_count=10, include_end=False)
    np.testing.assert_allclose(open_end, 100.0 + 10.0 * np.arange(10), rtol=RTOL_TIME, atol=0)
    np.testing.assert_array_equal(sspt_times_s(5.0, 9.0, frame_count=1), [5.0])
    np.testing.assert_array_equal(sspt_times_s(5.0, 5.0, frame_count=1), [5.0])


@pytest.mark.parametrize(
    ("start_s", "end_s", "step_s", "include_end", "expected_count", "last_s"),
    [
        (0.0, 10.0, 2.0, True, 6, 10.0),
        (0.0, 10.0, 2.0, False, 5, 8.0),
        (0.0, 10.5, 2.0, True, 6, 10.0),  # end off the grid: never a frame
        (0.0, 10.5, 2.0, False, 6, 10.0),
        (0.0, 1.0, 0.1, True, 11, 1.0),  # 10 * 0.1 lands on 1.0 within 1e-9 s
        (3.0, 3.0, 1.0, True, 1, 3.0),
        (-5.0, 5.0, 2.5, True, 5, 5.0),
    ],
)
def test_sspt_step_grid(start_s, end_s, step_s, include_end, expected_count, last_s) -> None:
    t = sspt_times_s(start_s, end_s, step_s=step_s, include_end=include_end)
    assert t.shape == (expected_count,)
    assert t[0] == start_s
    np.testing.assert_allclose(t[-1], last_s, rtol=RTOL_TIME, atol=1e-12)
    if expected_count > 1:
        np.testing.assert_allclose(np.diff(t), step_s, rtol=RTOL_TIME, atol=0)


def test_sspt_one_frame_every_k_seconds_on_a_long_segment() -> None:
    t = sspt_times_s(0.0, 5400.0, step_s=30.0)
    assert t.shape == (181,)
    np.testing.assert_allclose(np.diff(t), 30.0, rtol=RTOL_TIME, atol=0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"start_s": 10.0, "end_s": 5.0, "frame_count": 3}, "precede"),
        ({"start_s": 0.0, "end_s": 5.0}, "exactly one"),
        ({"start_s": 0.0, "end_s": 5.0, "frame_count": 3, "step_s": 1.0}, "exactly one"),
        ({"start_s": 0.0, "end_s": 5.0, "step_s": 0.0}, "positive"),
        ({"start_s": 0.0, "end_s": 5.0, "step_s": -1.0}, "positive"),
        ({"start_s": 0.0, "end_s": 5.0, "frame_count": 0}, "frame_count"),
        ({"start_s": 0.0, "end_s": 5.0, "frame_count": 2.0}, "frame_count"),
        ({"start_s": 0.0, "end_s": 0.0, "frame_count": 3}, "zero length"),
        ({"start_s": 0.0, "end_s": 0.0, "step_s": 1.0, "include_end": False}, "no frame"),
        ({"start_s": math.nan, "end_s": 5.0, "frame_count": 3}, "finite"),
    ],
)
def test_sspt_times_errors(kwargs, match) -> None:
    with pytest.raises(SatsightError, match=match):
        sspt_times_s(**kwargs)


def test_sspt_fly_around_at_five_degrees() -> None:
    period_s = 5760.0
    t = sspt_angle_times_s(period_s, 0.0, 360.0, 5.0)
    assert t.shape == (72,)
    np.testing.assert_allclose(t, np.arange(72) * period_s / 72, rtol=RTOL_TIME, atol=0)
    with_stop = sspt_angle_times_s(period_s, 0.0, 360.0, 5.0, include_stop=True)
    assert with_stop.shape == (73,)
    assert with_stop[-1] == period_s


def test_sspt_angle_times_phase_and_offset() -> None:
    # Angle a is reached at start_s + period a / 360; start_s is the epoch of 0 deg.
    t = sspt_angle_times_s(360.0, 90.0, 180.0, 30.0, start_s=1000.0)
    np.testing.assert_allclose(t, [1090.0, 1120.0, 1150.0], rtol=RTOL_TIME, atol=0)
    t = sspt_angle_times_s(360.0, 0.0, 100.0, 30.0, include_stop=True)  # stop off the grid
    np.testing.assert_allclose(t, [0.0, 30.0, 60.0, 90.0], rtol=RTOL_TIME, atol=0)
    # 0.1 deg steps: the float grid lands on the stop within tolerance.
    t = sspt_angle_times_s(360.0, 0.0, 1.0, 0.1, include_stop=True)
    assert t.shape == (11,)


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        ((0.0, 0.0, 360.0, 5.0), {}, "period_s"),
        ((100.0, 0.0, 360.0, 0.0), {}, "step_deg"),
        ((100.0, 0.0, 360.0, -5.0), {}, "step_deg"),
        ((100.0, 90.0, 0.0, 5.0), {}, "precede"),
        ((100.0, 10.0, 10.0, 5.0), {}, "no angle"),
        ((100.0, 0.0, math.inf, 5.0), {}, "finite"),
    ],
)
def test_sspt_angle_times_errors(args, kwargs, match) -> None:
    with pytest.raises(SatsightError, match=match):
        sspt_angle_times_s(*args, **kwargs)
    assert sspt_angle_times_s(100.0, 10.0, 10.0, 5.0, include_stop=True).shape == (1,)
