"""Distance intervals: the paper's bands, naming a range, sharing frames, drawing ranges."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from satsight.errors import SatsightError
from satsight.poses.distance_intervals import (
    APPROACH_INTERVALS_KM,
    HOVER_DISTANCE_KM,
    OUTSIDE_INTERVAL_NAME,
    DistanceInterval,
    balanced_counts,
    default_intervals,
    interval_name_for_range,
    sample_ranges_m,
)

Z_BOUND = 4.0  # standard errors allowed for a sample mean (two-sided p ~ 6e-5 per check)
P_MIN = 1e-3  # KS p-value floor; the seeds are fixed, so the outcome is too
SEED = 5


def _assert_mean_within(samples: np.ndarray, mean: float, std: float, what: str) -> None:
    se = std / math.sqrt(samples.size)
    got = float(samples.mean())
    assert abs(got - mean) < Z_BOUND * se, f"{what}: mean {got} vs {mean} (se {se})"


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
