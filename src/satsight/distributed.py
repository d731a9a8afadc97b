"""Frames rendered on a Dask distributed cluster: a LocalCluster of N worker processes
(``--workers N``) or an existing scheduler (``--scheduler ADDRESS``).

Each worker process builds the scenario's ``FrameEngine`` once (mesh, plan, sensor, the
renderer and its compiled kernels) and keeps it for every frame it is given. A task
renders one frame and writes its files into the dataset folder (shared by every worker:
the same machine, or a shared file system); it returns the frame's record, and only the
client appends records to the journal. A worker killed mid-frame loses nothing: Dask
runs its task again elsewhere, the files are rewritten with the same bytes, and the frame
is committed once, when its record reaches the client.

Dask is an optional dependency (``pip install satsight[dask]``).
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

from satsight.config.scenario import parse_scenario
from satsight.dataset.manifest import scenario_sha256
from satsight.errors import SatsightError

# Frames queued per worker beyond the one it renders, so no worker waits for the client.
_QUEUED_PER_WORKER = 2
_CONNECT_TIMEOUT_S = 10
_ENGINES: dict = {}
_ENCODERS: list[ThreadPoolExecutor] = []


def _worker_engine(scenario_json: dict):
    """This process's FrameEngine for a scenario, built on its first frame and kept."""
    from satsight.pipeline import FrameEngine

    key = scenario_sha256(scenario_json)
    if key not in _ENGINES:
        _ENGINES.clear()  # one scenario at a time per process
        _ENGINES[key] = FrameEngine(parse_scenario(scenario_json, "scenario"))
    if not _ENCODERS:
        from satsight.generation import ENCODER_THREADS

        _ENCODERS.append(ThreadPoolExecutor(ENCODER_THREADS))
    return _ENGINES[key]


def render_frame_task(scenario_json: dict, root: str, frame_index: int, variant: str) -> dict:
    """Render and write one frame on a worker; its journal record."""
    from satsight.generation import sense_frame, write_frame

    engine = _worker_engine(scenario_json)
    if engine.renderer.variant != variant:
        raise SatsightError(
            f"a worker renders with {engine.renderer.variant}, the dataset with {variant}; "
            "set render.variant in the scenario so that every worker uses the same one"
        )
    frame = engine.render(frame_index)
    record, _ = write_frame(engine, Path(root), sense_frame(engine, frame), _ENCODERS[0])
    return record


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore Ctrl-C while local worker processes start: they inherit the ignored signal,
    so a Ctrl-C in the terminal reaches only this process, which stops the run after the
    frames in flight (the workers would otherwise die with their frames)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextmanager
def dask_client(workers: int | None, scheduler: str | None) -> Iterator:
    """A Dask client: to a new LocalCluster of ``workers`` processes, or to the scheduler
    at ``scheduler``. Made before the dataset folder is touched, so that a missing Dask or
    an unreachable scheduler leaves nothing behind."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SatsightError(
            "--workers and --scheduler need Dask: pip install 'satsight[dask]' "
            "(or dask[distributed])"
        ) from None
    cluster = None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=f"{_CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as error:
            raise SatsightError(
                f"could not reach the Dask scheduler at {scheduler}: {error}"
            ) from None
    else:
        if workers is None or workers < 1:
            raise SatsightError(f"--workers must be a whole number >= 1, got {workers}")
        with _sigint_ignored():  # inherited by the worker processes
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_distributed(
    client,
    scenario_json: dict,
    root: Path,
    todo: list[int],
    commit: Callable[[dict], None],
    stop,
    variant: str,
) -> None:
    """Render the frames of ``todo`` on the client's workers; ``commit`` each record as it
    comes back."""
    from dask.distributed import as_completed

    workers = len(client.scheduler_info().get("workers", {}))
    window = max(1, workers) * (1 + _QUEUED_PER_WORKER)
    shared = client.scatter(scenario_json, broadcast=True)
    key = scenario_sha256(scenario_json)[:16]
    pending = iter(todo)
    futures = as_completed()
    submitted: list = []

    def submit_next() -> None:
        index = next(pending, None)
        if index is not None:
            submitted.append(
                client.submit(
                    render_frame_task,
                    shared,
                    str(root),
                    index,
                    variant,
                    key=f"satsight-{key}-frame-{index}",
                    pure=False,
                )
            )
            futures.add(submitted[-1])

    for _ in range(window):
        submit_next()
    for future in futures:
        try:
            record = future.result()
        except SatsightError:
            raise
        except Exception as error:
            if stop.is_set():
                break  # stopping anyway; this frame is not committed
            raise SatsightError(
                f"a frame failed on the Dask workers ({type(error).__name__}: {error}); "
                "the frames committed so far are kept: run again with --resume"
            ) from None
        commit(record)
        future.release()
        if stop.is_set():
            break
        submit_next()
    if stop.is_set():
        # The frames not yet committed are dropped; --resume renders them.
        client.cancel([f for f in submitted if not f.done()])
