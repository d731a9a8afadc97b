"""Worker threads of the sensor stages: how many, and running numbered jobs on them.

The sensor splits a frame into a fixed number of bands, a function of the image size only,
and runs one job per band; numpy's random generators, its ufuncs and scipy.fft release the
GIL, so the bands run in parallel. The result never depends on the thread count.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait

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


# Pools kept per calling thread (and process, and size): a frame runs 4-6 batches of jobs,
# and starting their threads each time cost 5 ms of a 20 ms sensor stage at 1024 x 1024
# (measured). One pool shared by the renderer's thread (the auto exposure's blur) and the
# sensor's made each wait for the other's jobs: 29 -> 45 ms a sensor stage in the pipeline.
# A thread's pools go with it (their threads end when the pool is collected).
_local = threading.local()
_in_job = threading.local()


def _pool(threads: int) -> ThreadPoolExecutor:
    """The calling thread's pool of up to ``threads`` threads, started as jobs need them
    (a new pool in a forked child)."""
    pools = getattr(_local, "pools", None)
    if pools is None:
        pools = _local.pools = {}
    key = (os.getpid(), threads)
    pool = pools.get(key)
    if pool is None:
        pool = pools[key] = ThreadPoolExecutor(threads, thread_name_prefix="satsight-jobs")
    return pool


def run_jobs(job: Callable[[int], object], count: int, threads: int) -> list:
    """job(0), ..., job(count - 1) on ``threads`` threads; their results in job order. Jobs
    started from a job run on its thread (a kept pool could otherwise wait on itself)."""
    if threads == 1 or count <= 1 or getattr(_in_job, "active", False):
        return [job(i) for i in range(count)]

    def run(i: int):
        _in_job.active = True
        try:
            return job(i)
        finally:
            _in_job.active = False

    # Every job ends before the call returns, even when one fails (then the first failure
    # in job order is raised): none goes on writing into its caller's arrays.
    pool = _pool(threads)
    futures = [pool.submit(run, i) for i in range(count)]
    wait(futures)
    return [future.result() for future in futures]
