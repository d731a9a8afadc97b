"""Worker threads of the sensor stages: how many, and running numbered jobs on them.

The sensor splits a frame into a fixed number of bands, a function of the image size only,
and runs one job per band; numpy's random generators, its ufuncs and scipy.fft release the
GIL, so the bands run in parallel. The result never depends on the thread count.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from satsight.errors import SatsightError


def check_threads(threads: int | None) -> int:
    """The number of worker threads: ``threads`` (>= 1), or every core this process may use."""
    if threads is None:
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # not on Linux
            return max(1, os.cpu_count() or 1)
    if isinstance(threads, bool) or not isinstance(threads, int | np.integer) or threads < 1:
        raise SatsightError(
            f"threads must be a whole number >= 1 or None (all cores), got {threads!r}"
        )
    return int(threads)


def run_jobs(job: Callable[[int], object], count: int, threads: int) -> list:
    """job(0), ..., job(count - 1) on ``threads`` threads; their results in job order."""
    if threads == 1 or count == 1:
        return [job(i) for i in range(count)]
    with ThreadPoolExecutor(max_workers=min(threads, count)) as pool:
        return list(pool.map(job, range(count)))
