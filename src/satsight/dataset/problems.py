"""Problems found in a dataset folder, and how many times each check ran.

``satsight validate`` collects every problem instead of stopping at the first; each one
names the frame and the file it concerns, what was expected and what came. A dataset of
10^6 frames may have 10^6 problems: every one is counted, per check, but only the first
``MAX_KEPT_PROBLEMS`` are kept in full.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

#: The checks of ``satsight validate``, in the order of its summary table.
CHECKS = {
    "complete": "complete.json present, its frame count and SHA-256 sums match",
    "manifest": "labels.json without its frames equals manifest.json",
    "journal": "labels.json frames equal the journal records",
    "indices": "frame indices 0 .. n-1 once each (n: manifest frame_count), plan indices",
    "files": "files exist, decode, and have the promised type, shape and values",
    "checksums": "file sizes and SHA-256 equal the frame's checksums",
    "pose": "unit quaternion with qw >= 0; keypoints, depths and range reproject from the pose",
    "masks": "box, pixel count and flags from the object mask; part mask and depth agree",
    "crop": "crop K, box, keypoints and files agree with the full frame",
}

#: Problems a ``Findings`` keeps in full; the ones after them are only counted.
MAX_KEPT_PROBLEMS = 1000


@dataclass(frozen=True)
class Problem:
    """One problem: which check found it, where, and what was expected and what came.

    frame: the frame index, None for the dataset as a whole. file: the file's path relative
    to the dataset folder, None when the problem is in a frame's record only.
    """

    check: str
    message: str
    frame: int | None = None
    file: str | None = None

    def __str__(self) -> str:
        where = [f"frame {self.frame}"] if self.frame is not None else []
        if self.file is not None:
            where.append(self.file)
        place = ", ".join(where) if where else "dataset"
        return f"{place}: {self.message} [{self.check}]"


@dataclass
class Findings:
    """Problems found so far, and how many items each check has looked at.

    problems: the first ``limit`` problems, in the order found. found: problems found per
    check, those beyond ``limit`` included. checked: items each check looked at.
    """

    problems: list[Problem] = field(default_factory=list)
    checked: Counter = field(default_factory=Counter)
    found: Counter = field(default_factory=Counter)
    limit: int = MAX_KEPT_PROBLEMS

    @property
    def total(self) -> int:
        """Problems found, kept or not."""
        return sum(self.found.values())

    @property
    def omitted(self) -> int:
        """Problems found but not kept (beyond ``limit``)."""
        return self.total - len(self.problems)

    def ran(self, check: str, count: int = 1) -> None:
        """Count ``count`` items looked at by ``check``."""
        self.checked[check] += count

    def add(
        self, check: str, message: str, frame: int | None = None, file: str | None = None
    ) -> None:
        """Record a problem found by ``check`` (kept in full while fewer than ``limit``)."""
        self.found[check] += 1
        if len(self.problems) < self.limit:
            self.problems.append(Problem(check, message, frame, file))

    def extend(self, other: Findings) -> None:
        """Take over another set of findings (in its order, up to ``limit`` kept)."""
        room = max(0, self.limit - len(self.problems))
        self.problems.extend(other.problems[:room])
        self.checked.update(other.checked)
        self.found.update(other.found)

    def counts(self) -> dict[str, tuple[int, int]]:
        """Check name -> (items checked, problems found), in the order of ``CHECKS``."""
        return {name: (self.checked[name], self.found[name]) for name in CHECKS}
