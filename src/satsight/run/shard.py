"""A shard of a dataset run: every count-th frame, so that several machines can split it."""

from __future__ import annotations

from dataclasses import dataclass

from satsight.errors import SatsightError


@dataclass(frozen=True)
class Shard:
    """Shard ``index`` (0-based) of ``count``: the frames with frame_index % count == index."""

    index: int
    count: int

    @classmethod
    def parse(cls, text: str) -> Shard:
        """A shard from ``K/N`` (K counted from 1, as a user says "shard 1 of 4")."""
        try:
            k, n = (int(part) for part in text.split("/"))
        except ValueError:
            raise SatsightError(f"--shard {text!r}: expected K/N, e.g. 1/4") from None
        if not 1 <= k <= n:
            raise SatsightError(f"--shard {text!r}: K must be between 1 and N")
        return cls(k - 1, n)

    def frames(self, frame_count: int) -> list[int]:
        return list(range(self.index, frame_count, self.count))

    def label(self) -> str:
        return f"{self.index + 1}/{self.count}"
