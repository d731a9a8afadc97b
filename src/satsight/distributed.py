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
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from satsight.config.scenario import parse_scenario
from satsight.dataset.manifest import scenario_sha256
from satsight.errors import SatsightError

# Frames queued per worker beyond the one it renders, so no worker waits for the client.
_QUEUED_PER_WORKER = 2
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


def _client(workers: int | None, scheduler: str | None):
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SatsightError(
            "--workers and --scheduler need Dask: pip install 'satsight[dask]' "
            "(or dask[distributed])"
        ) from None
    if scheduler is not None:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, TimeoutError) as error:
            raise SatsightError(
                f"could not reach the Dask scheduler at {scheduler}: {error}"
            ) from None
    if workers is None or workers < 1:
        raise SatsightError(f"--workers must be a whole number >= 1, got {workers}")
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster


def run_distributed(
    scenario_json: dict,
    root: Path,
    todo: list[int],
    commit: Callable[[dict], None],
    stop,
    workers: int | None,
    scheduler: str | None,
    variant: str,
) -> None:
    """Render the frames of ``todo`` on Dask workers; ``commit`` each record as it comes."""
    from dask.distributed import as_completed

    client, cluster = _client(workers, scheduler)
    try:
        slots = max(1, len(client.scheduler_info().get("workers", {})) or (workers or 1))
        window = slots * (1 + _QUEUED_PER_WORKER)
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
            commit(future.result())
            future.release()
            if stop.is_set():
                break
            submit_next()
        if stop.is_set():
            # The frames not yet committed are dropped; --resume renders them.
            client.cancel([f for f in submitted if not f.done()])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
