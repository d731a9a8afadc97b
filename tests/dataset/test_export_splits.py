"""The seeded train / val / test split shared by the exports."""

from __future__ import annotations

import math

import pytest

from satsight.dataset.export.splits import (
    SplitRule,
    assign_splits,
    parse_split,
    split_sizes,
)
from satsight.errors import SatsightError


def test_split_is_deterministic_for_a_seed_and_changes_with_it() -> None:
    frames = list(range(100))
    rule = SplitRule((0.8, 0.1, 0.1), seed=3)
    assert assign_splits(frames, rule) == assign_splits(list(reversed(frames)), rule)
    assert assign_splits(frames, rule) != assign_splits(frames, SplitRule((0.8, 0.1, 0.1), 4))


def test_split_is_a_partition_of_the_frames() -> None:
    frames = [3, 7, 8, 12, 40, 41, 42, 99, 100, 101, 250]
    splits = assign_splits(frames, SplitRule((0.6, 0.2, 0.2), seed=0))
    chosen = splits["train"] + splits["val"] + splits["test"]
    assert sorted(chosen) == frames  # every frame once
    assert all(s == sorted(s) for s in splits.values())


@pytest.mark.parametrize(
    ("n", "fractions", "expected"),
    [
        (10, (0.8, 0.1, 0.1), (8, 1, 1)),
        (4, (0.8, 0.1, 0.1), (3, 1, 0)),  # remainders 0.2, 0.4, 0.4: val wins the tie
        (7, (0.8, 0.1, 0.1), (5, 1, 1)),  # remainders 0.6, 0.7, 0.7: val and test
        (3, (1 / 3, 1 / 3, 1 / 3), (1, 1, 1)),
        (5, (0.5, 0.5, 0.0), (3, 2, 0)),  # tie 0.5 / 0.5 goes to train first
        (0, (0.8, 0.1, 0.1), (0, 0, 0)),
    ],
)
def test_sizes_follow_largest_remainder(n: int, fractions, expected) -> None:
    assert split_sizes(n, fractions) == expected


def test_sizes_sum_to_n_and_are_within_one_frame_of_the_fractions() -> None:
    for n in range(0, 60):
        for fractions in [(0.8, 0.1, 0.1), (0.7, 0.15, 0.15), (0.34, 0.33, 0.33), (1.0, 0, 0)]:
            sizes = split_sizes(n, fractions)
            assert sum(sizes) == n
            assert all(abs(s - n * f) < 1 for s, f in zip(sizes, fractions, strict=True))
    splits = assign_splits(list(range(57)), SplitRule((0.7, 0.2, 0.1), seed=9))
    assert tuple(len(s) for s in splits.values()) == split_sizes(57, (0.7, 0.2, 0.1))


def test_parse_split_accepts_three_fractions_summing_to_one() -> None:
    assert parse_split("0.8,0.1,0.1") == (0.8, 0.1, 0.1)
    assert parse_split(" 1 , 0 , 0 ") == (1.0, 0.0, 0.0)
    assert math.isclose(sum(parse_split("0.7,0.2,0.1")), 1.0)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("0.8,0.1", "three fractions"),
        ("0.8,0.1,0.2", "sum to 1"),
        ("a,b,c", "comma-separated numbers"),
        ("1.2,-0.1,-0.1", "between 0 and 1"),
        ("nan,0,1", "between 0 and 1"),
    ],
)
def test_parse_split_refuses_bad_values(text: str, says: str) -> None:
    with pytest.raises(SatsightError, match=says):
        parse_split(text)
