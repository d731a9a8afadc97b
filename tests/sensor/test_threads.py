"""The sensor's jobs: results in job order on kept pools, one per calling thread, jobs
started from a job run in place, errors passed on."""

from __future__ import annotations

import threading
import time

import pytest

from satsight.errors import SatsightError
from satsight.sensor.threads import check_threads, run_jobs


def _job_threads(count: int, threads: int) -> list[threading.Thread]:
    return run_jobs(lambda i: threading.current_thread(), count, threads)


def test_results_come_in_job_order_on_the_same_kept_threads() -> None:
    assert run_jobs(lambda i: i * i, 7, 3) == [0, 1, 4, 9, 16, 25, 36]
    seen = set()
    for _ in range(5):  # the pool starts its threads as it needs them, then keeps them
        seen |= set(_job_threads(12, 2))
    assert threading.current_thread() not in seen and 1 <= len(seen) <= 2


def test_one_thread_or_one_job_runs_in_the_calling_thread() -> None:
    me = threading.current_thread()
    assert _job_threads(3, 1) == [me] * 3
    assert _job_threads(1, 4) == [me]
    assert run_jobs(lambda i: i, 0, 2) == []


def test_each_calling_thread_has_its_own_pool() -> None:
    # Two callers at once (the renderer's thread and the sensor's, in a run): neither waits
    # for the other's jobs, and neither runs on the other's threads.
    barrier, done = threading.Barrier(2), threading.Barrier(2)
    seen: dict[str, set[threading.Thread]] = {}

    def caller(name: str) -> None:
        barrier.wait()
        seen[name] = set(_job_threads(8, 2))
        done.wait()  # both callers (and so their pools) alive until both are done

    callers = [threading.Thread(target=caller, args=(n,)) for n in ("a", "b")]
    for t in callers:
        t.start()
    for t in callers:
        t.join()
    assert seen["a"] and seen["b"] and not seen["a"] & seen["b"]


def test_jobs_started_from_a_job_run_on_its_thread() -> None:
    def outer(i: int) -> tuple[threading.Thread, set[threading.Thread]]:
        inner = set(_job_threads(4, 2))
        return threading.current_thread(), inner

    for ident, inner in run_jobs(outer, 4, 2):
        assert inner == {ident}


def test_a_failing_job_raises_in_the_caller_after_every_job_ended() -> None:
    finished = []

    def job(i: int) -> int:
        if i in (1, 3):
            raise ValueError(f"job {i}")
        time.sleep(0.02)
        finished.append(i)
        return i

    with pytest.raises(ValueError, match="job 1"):  # the first failure in job order
        run_jobs(job, 6, 2)
    assert sorted(finished) == [0, 2, 4, 5]  # none still running after the call
    assert run_jobs(lambda i: i, 4, 2) == [0, 1, 2, 3]  # the pool still works


def test_batches_of_any_size_keep_at_most_the_asked_threads() -> None:
    seen = set()
    for count in range(2, 12):
        seen |= set(_job_threads(count, 3))
    assert len(seen) <= 3


def test_thread_counts_are_checked() -> None:
    assert check_threads(3) == 3
    assert check_threads(None) >= 1
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(SatsightError, match="threads must be"):
            check_threads(bad)
