"""Fixtures shared by every test folder: the Mitsuba CPU variant, started once per session.

Named tolerances (ONE_MM, ARCSEC_RAD, ...) are module constants in ``tolerances.py``; small
shared builders and helpers are modules beside this file (``builders.py``, ``cli_runner.py``,
...), imported by name.
"""

from __future__ import annotations

import os

import pytest


def pytest_configure(config) -> None:
    """One BLAS thread per test process (and per program a test starts); under xdist one
    Dr.Jit thread per worker and per program it starts. The suite's
    workers already fill the cores, and OpenBLAS threads that wait on each other under that
    load make small solves tens of times slower (a 2292 x 10 SVD: 15 ms on two threads
    against 0.46 ms on one, with the suite running beside it). Results do not depend on it:
    the one fit whose bits would is pinned to one thread in the code."""
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    # ``--workers N`` starts its Dask workers even on this small machine, where a run would
    # otherwise render in one process (satsight.run.distributed.local_workers): the
    # tests of the distributed path need them; test_generation.py tests the fallback.
    os.environ["SATSIGHT_LOCAL_WORKERS"] = "always"
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
    if hasattr(config, "workerinput"):  # a pytest-xdist worker: its Dr.Jit pool too, and
        # that of every satsight program it starts (satsight.render.backend.use_variant)
        os.environ["SATSIGHT_RENDER_THREADS"] = "1"
        import drjit

        drjit.set_thread_count(1)


@pytest.fixture(scope="session")
def llvm_variant() -> str:
    """Start Mitsuba on the CPU backend once per test session."""
    from satsight.render.backend import CPU_VARIANT, use_variant

    return use_variant(CPU_VARIANT)
