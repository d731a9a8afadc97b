"""The seeded train / val / test split of a dataset's frames, shared by every export.

Rule (see docs/dataset_format.md, "Exports"):

1. Fractions ``(f_train, f_val, f_test)``, each in [0, 1], summing to 1 (within 1e-9).
2. Sizes by largest remainder: each split gets ``floor(n * f)`` frames; the frames left
   over go one each to the splits with the largest remainders ``n * f - floor(n * f)``,
   ties broken in the order train, val, test. The sizes sum to n and each differs from
   ``n * f`` by less than one frame.
3. Order: the frames sorted by ``frame_index`` are permuted by
   ``np.random.default_rng(np.random.SeedSequence([seed])).permutation(n)``; the first
   ``n_train`` of the permutation go to train, the next ``n_val`` to val, the rest to test.
   Each split lists its frames sorted by ``frame_index``.

The same dataset, fractions and seed give the same split on every machine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError

SPLIT_NAMES: tuple[str, str, str] = ("train", "val", "test")
DEFAULT_SPLIT = "0.8,0.1,0.1"
_SUM_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SplitRule:
    """Fractions of the frames in train, val and test, and the seed of their order."""

    fractions: tuple[float, float, float]
    seed: int = 0

    def __post_init__(self) -> None:
        check_fractions(self.fractions)
        if not isinstance(self.seed, int) or self.seed < 0:
            raise SatsightError(f"--seed must be a whole number >= 0, got {self.seed!r}")


def check_fractions(fractions: tuple[float, ...]) -> None:
    """Refuse fractions that are not three numbers in [0, 1] summing to 1."""
    if len(fractions) != 3:
        raise SatsightError(
            f"--split needs three fractions (train,val,test), got {len(fractions)}: "
            f"{list(fractions)}; for example --split {DEFAULT_SPLIT}"
        )
    for name, value in zip(SPLIT_NAMES, fractions, strict=True):
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise SatsightError(
                f"--split: the {name} fraction must be between 0 and 1, got {value!r}"
            )
    total = math.fsum(fractions)
    if abs(total - 1.0) > _SUM_TOLERANCE:
        raise SatsightError(
            f"--split fractions must sum to 1, these sum to {total:.12g}: "
            f"{','.join(f'{f:g}' for f in fractions)}; for example --split {DEFAULT_SPLIT}"
        )


def parse_split(text: str) -> tuple[float, float, float]:
    """Fractions of a ``--split`` value such as ``0.8,0.1,0.1`` (train, val, test)."""
    parts = [part.strip() for part in str(text).split(",")]
    try:
        values = tuple(float(part) for part in parts)
    except ValueError:
        raise SatsightError(
            f"--split {text!r} is not three comma-separated numbers (train,val,test); "
            f"for example --split {DEFAULT_SPLIT}"
        ) from None
    check_fractions(values)
    return values  # type: ignore[return-value]


def split_sizes(frame_count: int, fractions: tuple[float, float, float]) -> tuple[int, ...]:
    """Frames per split (train, val, test) by largest remainder; they sum to frame_count."""
    check_fractions(fractions)
    if frame_count < 0:
        raise SatsightError(f"frame count must be >= 0, got {frame_count}")
    exact = [frame_count * f for f in fractions]
    sizes = [math.floor(x) for x in exact]
    left = frame_count - sum(sizes)
    # Largest remainder first; Python's sort is stable, so ties keep train, val, test order.
    by_remainder = sorted(range(3), key=lambda k: exact[k] - sizes[k], reverse=True)
    for k in by_remainder[:left]:
        sizes[k] += 1
    return tuple(sizes)


def assign_splits(frame_indices: list[int], rule: SplitRule) -> dict[str, list[int]]:
    """Split name -> the frame indices in it (sorted), following the module's rule."""
    ordered = sorted(int(i) for i in frame_indices)
    if len(set(ordered)) != len(ordered):
        raise SatsightError("frame indices must be unique to be split")
    sizes = split_sizes(len(ordered), rule.fractions)
    rng = np.random.default_rng(np.random.SeedSequence([rule.seed]))
    permutation = rng.permutation(len(ordered))
    splits: dict[str, list[int]] = {}
    start = 0
    for name, size in zip(SPLIT_NAMES, sizes, strict=True):
        chosen = permutation[start : start + size]
        splits[name] = sorted(ordered[int(k)] for k in chosen)
        start += size
    return splits
