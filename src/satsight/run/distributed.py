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
import json
import logging
import os
import secrets
import signal
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import CancelledError, ThreadPoolExecutor
from contextlib import contextmanager, suppress
from pathlib import Path

from satsight.config.scenario import parse_scenario
from satsight.dataset.manifest import scenario_sha256
from satsight.errors import SatsightError
from satsight.frame_memory import FIXED_BYTES, memory_limit_bytes

log = logging.getLogger(__name__)

# Frames queued per worker beyond the one it renders, so no worker waits for the client.
_QUEUED_PER_WORKER = 2
_CONNECT_TIMEOUT_S = 10
#: Peak memory of a worker process per pixel of the frame, bytes, beyond
#: ``frame_memory.FIXED_BYTES``: one frame at a time (measured with a 1-worker LocalCluster,
#: example scenario, all outputs: peak RSS 0.64 GB at 128^2 px, 0.92 GB at 2048^2, 1.87 GB
#: at 4096^2, i.e. 69-73 bytes a pixel).
WORKER_BYTES_PER_PIXEL = 80.0
#: Times a frame lost with its worker (or with the scattered scenario) is submitted again.
MAX_FRAME_ATTEMPTS = 4
#: Address schemes Dask's Client connects to.
_SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")
_GB = 1e9
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
        from satsight.run.frame_stages import ENCODER_THREADS

        _ENCODERS.append(ThreadPoolExecutor(ENCODER_THREADS))
    return _ENGINES[key]


def render_frame_task(scenario_json: dict, root: str, frame_index: int, variant: str) -> dict:
    """Render and write one frame on a worker; its journal record."""
    from satsight.run.frame_stages import sense_frame, write_frame

    engine = _worker_engine(scenario_json)
    if engine.renderer.variant != variant:
        raise SatsightError(
            f"a worker renders with {engine.renderer.variant}, the dataset with {variant}; "
            "set render.variant in the scenario so that every worker uses the same one"
        )
    frame = engine.render(frame_index)
    record, _ = write_frame(engine, Path(root), sense_frame(engine, frame), _ENCODERS[0])
    return record


def scheduler_address(text: str) -> str:
    """The Dask address in ``--scheduler``: ``tcp://HOST:PORT`` (or another of Dask's
    schemes), ``HOST:PORT`` (TCP), or the path of a scheduler file (the JSON that
    ``dask scheduler --scheduler-file`` writes). A form Dask cannot connect to is refused
    here, in one line."""
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        raise SatsightError(
            "--scheduler needs Dask: pip install 'satsight[dask]' (or dask[distributed])"
        ) from None
    text = text.strip()
    usage = (
        "expected tcp://HOST:PORT, HOST:PORT or a scheduler file (the address "
        "`dask scheduler` prints, e.g. tcp://10.0.0.5:8786)"
    )
    if not text:
        raise SatsightError(f"--scheduler is empty: {usage}")
    if "://" not in text and (text.endswith(".json") or Path(text).is_file()):
        return _scheduler_file_address(Path(text), usage)
    scheme = text.split("://", 1)[0] if "://" in text else "tcp"
    if scheme not in _SCHEMES:
        raise SatsightError(
            f"--scheduler {text}: unknown scheme {scheme}:// (Dask knows "
            f"{', '.join(s + '://' for s in _SCHEMES)}); {usage}"
        )
    try:
        scheme, location = parse_address(text)
        if scheme == "inproc":
            return f"{scheme}://{location}"
        host, port = parse_host_port(location)
    except ValueError:
        raise SatsightError(f"--scheduler {text}: no port number; {usage}") from None
    if not host:
        raise SatsightError(f"--scheduler {text}: no host; {usage}")
    if not 1 <= port <= 65535:
        raise SatsightError(f"--scheduler {text}: port {port} is not in 1..65535; {usage}")
    return f"{scheme}://{location}"


def _scheduler_file_address(path: Path, usage: str) -> str:
    try:
        address = json.loads(path.read_text(encoding="utf-8"))["address"]
    except FileNotFoundError:
        raise SatsightError(f"--scheduler {path}: no such scheduler file; {usage}") from None
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise SatsightError(
            f"--scheduler {path}: not a Dask scheduler file (a JSON object with an "
            f"'address'; {type(error).__name__}: {error})"
        ) from None
    if not isinstance(address, str):
        raise SatsightError(f"--scheduler {path}: its 'address' is not text")
    return scheduler_address(address)


def _probe_scheduler(address: str, timeout_s: float = _CONNECT_TIMEOUT_S) -> None:
    """Check that a Dask scheduler answers at the TCP ``address`` within ``timeout_s``;
    else one line saying what is there instead (no host, nothing listening, silence, an
    HTTP server, another program).

    A Dask scheduler speaks first: on a new connection it sends its handshake, a Dask
    message (8-byte little-endian length, then frames) before reading the client's.
    Dask's own connect reads that handshake without a time limit, so a server that says
    nothing (an HTTP server waits for a request) would hold the run forever.
    """
    from distributed.comm.addressing import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme != "tcp":
        return  # TLS, WebSocket, UCX: Dask's connect, under its own timeout
    host, port = parse_host_port(location)
    where = f"could not reach the Dask scheduler at {address}"
    try:
        stream = socket.create_connection((host, port), timeout=timeout_s)
    except socket.gaierror:
        raise SatsightError(
            f"{where}: the host name {host} is not known; check --scheduler"
        ) from None
    except ConnectionRefusedError:
        raise SatsightError(
            f"{where}: nothing listens on port {port} of {host} (connection refused); "
            f"start one there (dask scheduler --port {port}) or check --scheduler"
        ) from None
    except TimeoutError:
        raise SatsightError(
            f"{where}: no answer to a connection in {timeout_s:g} s (the host is down or "
            "a firewall drops the port)"
        ) from None
    except OSError as error:
        raise SatsightError(f"{where}: {error.strerror or error}") from None
    with stream:
        first = _receive(stream, 16, timeout_s)
        if first is None:
            found = _http_server(host, port)
            raise SatsightError(
                f"{where}: {found or 'a program'} listens there but sent no Dask "
                f"handshake in {timeout_s:g} s; give the scheduler's own port (8786 unless set; "
                "the dashboard's 8787 is an HTTP server)"
            )
        if len(first) < 16 or not _looks_like_dask(first):
            first += _receive(stream, 48, 0.5) or b""  # the rest of a greeting line
            shown = first.split(b"\r\n", 1)[0][:40].decode("ascii", "replace")
            kind = "an HTTP server" if first.startswith(b"HTTP/") else "a program"
            raise SatsightError(
                f"{where}: {kind} there answered {shown!r}, not a Dask handshake; "
                "check --scheduler (the scheduler's port is 8786 unless set)"
            )


def _receive(stream: socket.socket, size: int, timeout_s: float) -> bytes | None:
    """Up to ``size`` bytes the peer sends within ``timeout_s`` (None: silence)."""
    stream.settimeout(timeout_s)
    data = b""
    deadline = time.monotonic() + timeout_s
    try:
        while len(data) < size and time.monotonic() < deadline:
            stream.settimeout(max(deadline - time.monotonic(), 0.01))
            chunk = stream.recv(size - len(data))
            if not chunk:
                break
            data += chunk
    except TimeoutError:
        pass
    except OSError:
        return data or None
    return data or None


def _looks_like_dask(first: bytes) -> bool:
    """The first 16 bytes of a Dask TCP message: the byte count of what follows, then
    the number of frames, both little-endian uint64 and small for a handshake."""
    total, frames = struct.unpack("<QQ", first[:16])
    return 0 < total < 2**24 and 0 < frames < 2**10


def _http_server(host: str, port: int) -> str | None:
    """'an HTTP server (Server: ...)' when one answers a GET at host:port, else None."""
    try:
        with socket.create_connection((host, port), timeout=3) as stream:
            stream.sendall(f"HEAD / HTTP/1.0\r\nHost: {host}\r\n\r\n".encode("ascii"))
            reply = _receive(stream, 1024, 3.0) or b""
    except OSError:
        return None
    if not reply.startswith(b"HTTP/"):
        return None
    server = [
        line.split(b":", 1)[1].strip().decode("ascii", "replace")
        for line in reply.split(b"\r\n")
        if line.lower().startswith(b"server:")
    ]
    return "an HTTP server" + (f" ({server[0]})" if server else "")


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
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
        cores = cores or os.cpu_count() or 1
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


def worker_memory_bytes(width_px: int, height_px: int) -> float:
    """Estimated peak memory (bytes) of one worker process rendering width x height px
    frames: the run's fixed cost and one frame's buffers (a worker renders one frame at
    a time)."""
    return FIXED_BYTES + WORKER_BYTES_PER_PIXEL * float(width_px) * float(height_px)


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
        _probe_scheduler(address)
        try:
            client = Client(address, timeout=f"{_CONNECT_TIMEOUT_S}s")
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
        if out_dir is not None:
            check_workers_write(client, out_dir)
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
        client.wait_for_workers(1, timeout=6 * _CONNECT_TIMEOUT_S)
        shared[0] = client.scatter([scenario_json], broadcast=True, hash=False)[0]
    except (OSError, TimeoutError) as failure:
        raise SatsightError(
            f"the Dask cluster lost its workers and has none back after "
            f"{6 * _CONNECT_TIMEOUT_S} s ({failure}); the frames committed so far are "
            "kept: run again with --resume"
        ) from None
