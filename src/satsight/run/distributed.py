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

import hashlib
import logging
import os
import secrets
import socket
from collections.abc import Callable, Iterator
from concurrent.futures import CancelledError
from contextlib import contextmanager, suppress
from pathlib import Path

from satsight.dataset.manifest import scenario_sha256
from satsight.errors import SatsightError
from satsight.frame_memory import frame_memory_bytes, memory_limit_bytes
from satsight.render.backend import machine_cores
from satsight.run.frame_tasks import make_frame
from satsight.run.interrupt import sigint_ignored
from satsight.run.scheduler_address import CONNECT_TIMEOUT_S, probe_scheduler, scheduler_address

log = logging.getLogger(__name__)

# Frames queued per worker beyond the one it renders, so no worker waits for the client.
_QUEUED_PER_WORKER = 2
#: Cores one process keeps busy (``local_workers``).
CORES_PER_PROCESS = 2
#: Times a frame lost with its worker (or with the scattered scenario) is submitted again.
MAX_FRAME_ATTEMPTS = 4
_GB = 1e9


def render_frame_task(scenario_json: dict, root: str, frame_index: int, variant: str) -> dict:
    """Render and write one frame on a worker; its journal record."""
    return make_frame(scenario_json, root, frame_index, variant)[0]


def local_worker_cap(
    requested: int,
    width_px: int,
    height_px: int,
    cores: int | None = None,
    memory_bytes: float | None = None,
) -> tuple[int, str | None]:
    """How many local worker processes this machine holds for width x height px frames,
    and why fewer than ``requested`` (None when all fit).

    One worker per core (each renders on all of its process's threads and has compiled
    kernels of its own: more workers than cores only share the cores and multiply the
    memory), and as many as fit in ``memory_bytes`` (default: ``memory_limit_bytes()``,
    the machine's available memory or ``SATSIGHT_MEMORY_LIMIT_GB``) at
    ``worker_memory_bytes`` each. Never fewer than 1.
    """
    if cores is None:
        cores = machine_cores()
    if memory_bytes is None:
        memory_bytes = memory_limit_bytes()
    per_worker = worker_memory_bytes(width_px, height_px)
    by_memory = requested if memory_bytes is None else int(memory_bytes // per_worker)
    cap = max(1, min(requested, cores, by_memory))
    if cap >= requested:
        return requested, None
    memory = (
        "" if memory_bytes is None
        else f", {memory_bytes / _GB:.1f} GB available at about {per_worker / _GB:.1f} GB "
        f"per worker for {width_px} x {height_px} px frames"
    )  # fmt: skip
    return cap, (
        f"--workers {requested}: this machine holds {cap} ({cores} "
        f"core{'s' * (cores != 1)}{memory}); "
        f"starting {cap} worker processes"
    )


def local_workers(requested: int, cores: int | None = None) -> tuple[int | None, str | None]:
    """How many local workers ``--workers requested`` starts (None: the run renders in this
    process instead), and why not as many as asked (None when it starts them all).

    One process already keeps ``CORES_PER_PROCESS`` cores busy: the renderer's threads on
    one frame while the sensor and the encoders take the one before. A local worker renders,
    senses and writes its frames one after another, so it needs as many to be worth its
    start-up (a process, its scenario, plan, star catalogue and compiled kernels): measured
    on 2 cores, 20 frames of the RSSF example at 1024 x 1024, one process 6.6 s, ``--workers
    2`` 10.3 s (10.3 s too with one render thread each). So at most one worker per
    ``CORES_PER_PROCESS`` cores starts, and none unless two can; the environment variable
    ``SATSIGHT_LOCAL_WORKERS=always`` starts them all anyway (to try a cluster's setup on a
    small machine; ``local_worker_cap`` still holds them to the cores and the memory)."""
    if os.environ.get("SATSIGHT_LOCAL_WORKERS", "").strip().lower() == "always":
        return requested, None
    if cores is None:
        cores = machine_cores()
    count = min(requested, cores // CORES_PER_PROCESS)
    if count >= max(requested, 2):
        return requested, None
    where = f"on {cores} core{'s' * (cores != 1)}"
    if count < 2:
        return None, (
            f"--workers {requested}: rendering in this process instead; {where} one process "
            "keeps them busy and worker processes would only add their start-up "
            "(SATSIGHT_LOCAL_WORKERS=always starts them anyway; --scheduler renders on a "
            "cluster)"
        )
    return count, (
        f"--workers {requested}: starting {count}, {CORES_PER_PROCESS} cores each {where} "
        "(SATSIGHT_LOCAL_WORKERS=always starts them all)"
    )


def worker_memory_bytes(width_px: int, height_px: int) -> float:
    """Estimated peak memory (bytes) of one worker process rendering width x height px
    frames: one frame at a time, Dr.Jit's buffers kept (``frame_memory.frame_memory_bytes``
    with ``kept``; a 1-worker LocalCluster, example scenario, all outputs, peaked at 0.64 GB
    at 128^2 px, 0.92 GB at 2048^2, 1.87 GB at 4096^2)."""
    return frame_memory_bytes(width_px, height_px, kept=True)


def _probe_name(token: str, worker: str) -> str:
    return f".satsight-probe-{token}-{hashlib.sha256(worker.encode()).hexdigest()[:12]}"


def _write_probe(folder: str, token: str, dask_worker=None) -> str | None:
    """On a worker: write its probe file into ``folder``; None, or why it could not."""
    name = _probe_name(token, dask_worker.address)
    try:
        with open(os.path.join(folder, name), "x", encoding="utf-8") as stream:
            stream.write(f"{dask_worker.address} {token}")
    except OSError as error:
        return error.strerror or str(error)
    return None


def _remove_probe(folder: str, token: str, dask_worker=None) -> None:
    with suppress(OSError):
        os.unlink(os.path.join(folder, _probe_name(token, dask_worker.address)))


def check_workers_write(client, folder: Path) -> None:
    """Every worker writes a probe file into ``folder`` (an absolute path) and the client
    reads each back: the dataset folder must be one that every worker writes to and this
    process sees, at the same path (the same machine, or a shared file system). The
    probe files are removed again."""
    folder = Path(os.path.abspath(folder))
    token = secrets.token_hex(8)
    try:
        errors = client.run(_write_probe, str(folder), token)
    except Exception as error:
        raise SatsightError(
            f"could not ask the Dask workers to write into {folder} "
            f"({type(error).__name__}: {error})"
        ) from None
    try:
        for worker, error in errors.items():
            if error is not None:
                raise SatsightError(
                    f"the Dask worker at {worker} cannot write into {folder} ({error}); "
                    "give --out a folder that every worker can write to, at the same path"
                )
            path = folder / _probe_name(token, worker)
            try:
                seen = path.read_text(encoding="utf-8") == f"{worker} {token}"
            except OSError:
                seen = False
            if not seen:
                raise SatsightError(
                    f"the Dask worker at {worker} wrote into a folder {folder} that this "
                    f"machine ({socket.gethostname()}) does not see: give --out a folder "
                    "shared by every worker and this machine, at the same path"
                )
    finally:
        for worker in errors:
            (folder / _probe_name(token, worker)).unlink(missing_ok=True)
        with suppress(Exception):
            client.run(_remove_probe, str(folder), token)


@contextmanager
def dask_client(
    workers: int | None,
    scheduler: str | None,
    out_dir: Path | None = None,
    frame_px: tuple[int, int] = (0, 0),
) -> Iterator:
    """A Dask client: to a new LocalCluster of ``workers`` processes (fewer where the
    machine holds fewer of ``frame_px`` = (width, height) frames: ``local_worker_cap``),
    or to the scheduler at ``scheduler``. Made before anything but the (locked, empty)
    dataset folder ``out_dir`` exists, so that a missing Dask, an unreachable scheduler or
    workers that cannot write into ``out_dir`` leave nothing behind."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SatsightError(
            "--workers and --scheduler need Dask: pip install 'satsight[dask]' "
            "(or dask[distributed])"
        ) from None
    cluster = None
    if scheduler is not None:
        address = scheduler_address(scheduler)
        probe_scheduler(address)
        try:
            client = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as error:
            raise SatsightError(
                f"could not reach the Dask scheduler at {address}: {error}"
            ) from None
    else:
        if workers is None or workers < 1:
            raise SatsightError(f"--workers must be a whole number >= 1, got {workers}")
        workers, why = local_worker_cap(workers, *frame_px)
        if why is not None:
            log.warning("%s", why)
        # The cores shared out: each worker's renderer gets its share of the threads
        # (unless SATSIGHT_RENDER_THREADS says otherwise), not one thread per core each.
        threads = os.environ.get("SATSIGHT_RENDER_THREADS") or str(
            max(1, machine_cores() // workers)
        )
        with sigint_ignored():  # inherited by the worker processes
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                env={"SATSIGHT_RENDER_THREADS": threads},
                processes=True,
                # Any free port: with None the scheduler's HTTP server still takes 8787,
                # and a second run on the machine warns that it is in use.
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            )
        client = Client(cluster)
    try:
        if out_dir is not None:
            check_workers_write(client, out_dir)
        yield client
    finally:
        if cluster is not None:
            # Workers that heartbeat while the cluster shuts them down log the closed
            # connection as an error with its traceback; the run has ended, so say nothing.
            with suppress(OSError, TimeoutError):
                client.run(_quiet_distributed_logs, on_error="ignore")
        client.close()
        if cluster is not None:
            cluster.close()


def _quiet_distributed_logs() -> None:
    """Only critical messages from Dask in this process (a local worker being shut down)."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL)


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
    comes back.

    ``root`` is sent as an absolute path (a worker's working folder is its own). A frame
    lost with a worker, or with the scattered scenario (the scheduler keeps one copy of
    it, and a copy dies with its worker), is submitted again, at most
    ``MAX_FRAME_ATTEMPTS`` times in all."""
    from dask.distributed import as_completed
    from distributed.scheduler import KilledWorker

    root = Path(os.path.abspath(root))
    workers = len(client.scheduler_info().get("workers", {}))
    window = max(1, workers) * (1 + _QUEUED_PER_WORKER)
    key = scenario_sha256(scenario_json)[:16]
    # One object (a dict itself would be scattered value by value, under its own keys).
    shared = [client.scatter([scenario_json], broadcast=True, hash=False)[0]]
    pending = iter(todo)
    futures = as_completed()
    submitted: dict = {}  # future -> frame index
    attempts: dict[int, int] = {}

    def submit(index: int) -> None:
        attempt = attempts.get(index, 0)
        attempts[index] = attempt + 1
        future = client.submit(
            render_frame_task,
            shared[0],
            str(root),
            index,
            variant,
            key=f"satsight-{key}-frame-{index}" + (f"-again-{attempt}" if attempt else ""),
            pure=False,
        )
        submitted[future] = index
        futures.add(future)

    def submit_next() -> None:
        index = next(pending, None)
        if index is not None:
            submit(index)

    for _ in range(window):
        submit_next()
    for future in futures:
        index = submitted.pop(future)
        try:
            record = future.result()
        except SatsightError:
            raise
        except (CancelledError, KilledWorker) as error:
            if stop.is_set():
                break  # stopping anyway; this frame is not committed
            _resubmit_lost_frame(client, index, attempts[index], error, shared, scenario_json)
            submit(index)
            continue
        except Exception as error:
            if stop.is_set():
                break
            raise SatsightError(
                f"frame {index} failed on the Dask workers ({type(error).__name__}: "
                f"{error}); the frames committed so far are kept: run again with --resume"
            ) from None
        commit(record)
        future.release()
        if stop.is_set():
            break
        submit_next()
    if stop.is_set():
        # The frames not yet committed are dropped; --resume renders them.
        client.cancel([f for f in submitted if not f.done()])


def _resubmit_lost_frame(client, index, attempts, error, shared, scenario_json) -> None:
    """Get ready to submit frame ``index`` again after it was lost (``error``), or say why
    not: it was tried ``MAX_FRAME_ATTEMPTS`` times, or the cluster has no worker left.
    Scatters the scenario again when its copy was lost with its worker."""
    from distributed.scheduler import KilledWorker

    if isinstance(error, KilledWorker) or attempts >= MAX_FRAME_ATTEMPTS:
        raise SatsightError(
            f"frame {index} was lost with its Dask worker {attempts} times (or killed "
            "the workers that rendered it: out of memory? see the workers' logs); the "
            "frames committed so far are kept: run again with --resume"
        )
    log.warning(
        "frame %d was lost with a Dask worker (%s); rendering it again", index,
        type(error).__name__,
    )  # fmt: skip
    if shared[0].status == "finished":
        return
    try:
        client.wait_for_workers(1, timeout=6 * CONNECT_TIMEOUT_S)
        shared[0] = client.scatter([scenario_json], broadcast=True, hash=False)[0]
    except (OSError, TimeoutError) as failure:
        raise SatsightError(
            f"the Dask cluster lost its workers and has none back after "
            f"{6 * CONNECT_TIMEOUT_S} s ({failure}); the frames committed so far are "
            "kept: run again with --resume"
        ) from None
