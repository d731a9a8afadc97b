"""Argument checks shared by the viewpoint samplers (``satsight.poses.sspt``,
``satsight.poses.rssf``, ``satsight.poses.distance_intervals``): each returns the checked
value or raises a one-line ``SatsightError`` that says what was expected."""

from __future__ import annotations

import math
import operator

import numpy as np

from satsight.errors import SatsightError


def check_generator(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise SatsightError(
            f"expected a numpy random Generator, got {type(rng).__name__}; "
            "pass one explicitly, e.g. rng=np.random.default_rng(5)"
        )
    return rng


def check_count(value: object, what: str, minimum: int) -> int:
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


def check_finite(value: object, what: str) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise SatsightError(f"{what} must be a real number, got {value!r}") from None
    if not math.isfinite(number):
        raise SatsightError(f"{what} must be finite, got {number}")
    return number
