"""Dask at its edges: scheduler addresses of every form, something other than a scheduler
at the address, more local workers than the machine holds, workers killed mid-run (with
the one copy of the scattered scenario), a relative --out with workers started in another
folder, and workers that cannot write the dataset folder. Each run is checked against a
single-process run byte for byte, or for leaving nothing behind."""

from __future__ import annotations

import http.server
import logging
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from functools import partial
from pathlib import Path

import pytest

from cli_runner import run_satsight
from dataset_files import file_hashes, generated_dataset, write_scenario_yaml
from satsight.config.scenario import parse_scenario
from satsight.dataset.journal import read_journal
from satsight.errors import SatsightError
from satsight.run import distributed
from satsight.run.distributed import local_worker_cap, worker_memory_bytes
from satsight.run.generation import generate_dataset
from satsight.run.scheduler_address import probe_scheduler, scheduler_address

dask_distributed = pytest.importorskip("dask.distributed")

FRAME_COUNT = 6
GB = 1e9
_WRITE_PROBE, _REMOVE_PROBE = distributed._write_probe, distributed._remove_probe


def scenario_dict() -> dict:
    frames = [
        {"distance_km": 0.03 + 0.004 * i, "azimuth_deg": 41.0 * i, "elevation_deg": 9.0 * i}
        for i in range(FRAME_COUNT)
    ]
    return {
        "name": "distributed-edges",
        "seed": 11,
        "camera": {"preset": "wide_field", "width_px": 96, "height_px": 72},
        "target": {"procedural": {"satellite_class": "two_wings", "seed": 3}},
        "frames": frames,
        "render": {"bounces": 1},
    }


@pytest.fixture(scope="module")
def reference_hashes(tmp_path_factory) -> dict[str, str]:
    """The files of a single-process run."""
    out = tmp_path_factory.mktemp("reference") / "dataset"
    return file_hashes(generated_dataset(out, scenario_dict()))


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory) -> Path:
    return write_scenario_yaml(tmp_path_factory.mktemp("scenario"), scenario_dict())


def cluster(**options):
    """A LocalCluster of 2 single-threaded worker processes under nannies."""
    return dask_distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0", **options
    )


# --- the scheduler's address ---------------------------------------------------------------
def test_scheduler_address_forms_dask_accepts(tmp_path: Path) -> None:
    assert scheduler_address("10.0.0.5:8786") == "tcp://10.0.0.5:8786"
    assert scheduler_address(" tcp://head-node:8786 ") == "tcp://head-node:8786"
    assert scheduler_address("tcp://[::1]:8786") == "tcp://[::1]:8786"
    assert scheduler_address("tls://head:8786") == "tls://head:8786"
    assert scheduler_address("inproc://10.0.0.5/123/1") == "inproc://10.0.0.5/123/1"
    file = tmp_path / "scheduler.json"
    file.write_text('{"type": "Scheduler", "address": "tcp://10.1.2.3:8786"}')
    assert scheduler_address(str(file)) == "tcp://10.1.2.3:8786"
    other_name = tmp_path / "cluster-info"
    other_name.write_text('{"address": "10.1.2.4:8786"}')
    assert scheduler_address(str(other_name)) == "tcp://10.1.2.4:8786"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("banana", "--scheduler banana: no port number"),
        ("tcp://banana", "no port number"),
        ("banana:eight", "no port number"),
        ("[::1]", "no port number"),
        ("tcp://:8786", "no host"),
        ("head:0", "port 0 is not in 1..65535"),
        ("head:99999", "port 99999 is not in 1..65535"),
        ("http://head:8787", "unknown scheme http://"),
        ("", "--scheduler is empty"),
        ("missing.json", "no such scheduler file"),
    ],
)
def test_bad_scheduler_addresses_are_one_line(text: str, message: str) -> None:
    with pytest.raises(SatsightError, match=re.escape(message)) as caught:
        scheduler_address(text)
    assert "\n" not in str(caught.value)


def test_a_bad_scheduler_file_names_what_is_wrong(tmp_path: Path) -> None:
    file = tmp_path / "scheduler.json"
    file.write_text("{not json")
    with pytest.raises(SatsightError, match="not a Dask scheduler file"):
        scheduler_address(str(file))
    file.write_text('{"address": "banana"}')
    with pytest.raises(SatsightError, match="--scheduler banana: no port number"):
        scheduler_address(str(file))


def test_cli_refuses_a_bad_scheduler_address_at_once(tmp_path: Path, scenario_file: Path):
    out = tmp_path / "out"
    result = run_satsight(
        "generate", str(scenario_file), "--out", str(out), "--scheduler", "banana", cwd=tmp_path
    )
    assert result.returncode == 2
    assert "error: --scheduler banana: no port number; expected tcp://HOST:PORT" in result.stderr
    assert "Traceback" not in result.stderr and "ValueError" not in result.stderr
    assert not out.exists()


# --- what answers at the address -----------------------------------------------------------
class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@pytest.fixture()
def http_port():
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Quiet)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.server_address[1]
    server.shutdown()
    server.server_close()


def _listener(reply: bytes | None):
    """A TCP server on a free port that accepts connections and sends ``reply`` (or
    nothing), keeping them open; its port and a function that closes it."""
    server = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []
    stopping = threading.Event()

    def serve() -> None:
        server.settimeout(0.2)
        while not stopping.is_set():
            try:
                connection, _ = server.accept()
            except OSError:
                continue
            if reply is not None:
                connection.sendall(reply)
            held.append(connection)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()

    def close() -> None:
        stopping.set()
        thread.join()
        for connection in held:
            connection.close()
        server.close()

    return server.getsockname()[1], close


def test_an_http_server_at_the_address_is_named_within_the_time_limit(
    tmp_path: Path, http_port: int, monkeypatch
) -> None:
    """Dask's own connect waits without a limit for the handshake an HTTP server never
    sends; the run stops after the probe's limit and says what answered. The limit is
    the probe's argument (10 s unless given); the run here gives it 1 s, so stopping in
    well under 10 s shows the run waits for the limit it gives, not for Dask."""
    limit_s = 1.0
    monkeypatch.setattr(distributed, "probe_scheduler", partial(probe_scheduler, timeout_s=limit_s))
    out = tmp_path / "out"
    started = time.monotonic()
    with pytest.raises(SatsightError) as caught:
        generate_dataset(
            parse_scenario(scenario_dict()), out, scheduler=f"tcp://127.0.0.1:{http_port}"
        )
    assert limit_s <= time.monotonic() - started < 10
    message = str(caught.value)
    assert f"could not reach the Dask scheduler at tcp://127.0.0.1:{http_port}" in message
    assert "an HTTP server (SimpleHTTP" in message and "no Dask handshake in 1 s" in message
    assert "8786" in message and "\n" not in message
    assert not out.exists()


def test_a_silent_program_and_another_protocol_are_named() -> None:
    port, close = _listener(None)
    try:
        started = time.monotonic()
        with pytest.raises(SatsightError, match=r"a program listens there but sent no Dask"):
            probe_scheduler(f"tcp://127.0.0.1:{port}", timeout_s=1.0)
        assert time.monotonic() - started < 10
    finally:
        close()
    port, close = _listener(b"SSH-2.0-OpenSSH_9.2p1\r\n")
    try:
        with pytest.raises(SatsightError, match=r"answered 'SSH-2.0-OpenSSH_9.2p1', not a Dask"):
            probe_scheduler(f"tcp://127.0.0.1:{port}", timeout_s=1.0)
    finally:
        close()


def test_a_closed_port_and_an_unknown_host_fail_at_once() -> None:
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]  # free once closed
    started = time.monotonic()
    with pytest.raises(SatsightError, match=rf"nothing listens on port {port} of 127.0.0.1"):
        probe_scheduler(f"tcp://127.0.0.1:{port}")
    with pytest.raises(SatsightError, match=r"the host name no-such-host\.invalid is not known"):
        probe_scheduler("tcp://no-such-host.invalid:8786")
    assert time.monotonic() - started < 10


def test_a_real_scheduler_passes_the_probe() -> None:
    with dask_distributed.LocalCluster(
        n_workers=0, processes=True, dashboard_address=":0", protocol="tcp"
    ) as local:
        assert local.scheduler_address.startswith("tcp://")
        probe_scheduler(local.scheduler_address, timeout_s=5.0)


# --- how many local workers ----------------------------------------------------------------
def test_workers_are_capped_by_cores_and_by_memory(monkeypatch) -> None:
    assert local_worker_cap(2, 96, 72, cores=2, memory_bytes=20 * GB) == (2, None)
    count, why = local_worker_cap(64, 96, 72, cores=2, memory_bytes=20 * GB)
    assert count == 2
    assert why.startswith("--workers 64: this machine holds 2 (2 cores, 20.0 GB available")
    per_worker = worker_memory_bytes(4096, 4112)
    assert 1.5 * GB < per_worker < 3.0 * GB  # measured peak of a 4096^2 worker: 1.87 GB
    count, why = local_worker_cap(16, 4096, 4112, cores=16, memory_bytes=5 * GB)
    assert count == int(5 * GB // per_worker) == 2
    assert f"about {per_worker / GB:.1f} GB per worker for 4096 x 4112 px frames" in why
    assert local_worker_cap(8, 4096, 4112, cores=16, memory_bytes=1 * GB)[0] == 1  # never 0
    monkeypatch.setenv("SATSIGHT_MEMORY_LIMIT_GB", "off")  # no memory figure: cores only
    count, why = local_worker_cap(8, 96, 72, cores=4)
    assert (
        count == 4
        and why == "--workers 8: this machine holds 4 (4 cores); starting 4 worker processes"
    )
    monkeypatch.setenv("SATSIGHT_MEMORY_LIMIT_GB", "2")
    assert local_worker_cap(8, 96, 72, cores=4)[0] == int(2 * GB // worker_memory_bytes(96, 72))


def test_more_workers_than_cores_start_as_many_as_cores(
    tmp_path: Path, scenario_file: Path, reference_hashes
) -> None:
    """--workers 64 on one core (taskset): one worker, a line saying so, the same bytes."""
    taskset = shutil.which("taskset")
    if taskset is None:
        pytest.skip("taskset is not installed")
    out = tmp_path / "out"
    result = subprocess.run(
        [taskset, "-c", "0", sys.executable, "-m", "satsight", "generate", str(scenario_file),
         "--out", str(out), "--workers", "64"],
        capture_output=True, text=True, timeout=300, check=False, cwd=tmp_path,
        env={**os.environ, "COLUMNS": "200"},
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "--workers 64: this machine holds 1 (1 core, " in result.stderr
    assert "starting 1 worker processes" in result.stderr
    assert file_hashes(out) == reference_hashes


def kill_scenario_holders(local) -> list[int]:
    """SIGKILL the worker processes of ``local`` that hold the scattered scenario (read
    from the cluster's scheduler, which runs in this process); their pids."""
    pids = {nanny.worker_address: nanny.process.pid for nanny in local.workers.values()}
    holders = {
        worker.address
        for key, task in list(local.scheduler.tasks.items())
        if str(key).startswith("dict-") and task.state == "memory"
        for worker in task.who_has
    }
    assert holders, "the scattered scenario is on some worker"
    for address in holders:
        os.kill(pids[address], signal.SIGKILL)
    return [pids[address] for address in holders]


# --- workers killed mid-run ----------------------------------------------------------------
# After the first commit most frames are in flight or queued when the holders die; after
# the fifth only the last one is. A kill in between takes the same path as these two.
@pytest.mark.parametrize("kill_after", [1, 5])
def test_killing_the_workers_that_hold_the_scenario_loses_no_frame(
    tmp_path: Path, reference_hashes, kill_after: int, caplog
) -> None:
    """The scheduler keeps the scattered scenario on one worker or a few (its memory
    manager drops extra copies); killing the workers that hold it cancels every frame
    that needs it. The frames are submitted again (with the scenario scattered again to
    the restarted workers) and the dataset is the single-process one."""
    with cluster() as local:
        killed: list[int] = []

        def on_frame_done(done: int, total: int) -> None:
            if done == kill_after and not killed:
                killed.extend(kill_scenario_holders(local))

        out = tmp_path / "dataset"
        with caplog.at_level(logging.WARNING, logger="satsight.run.distributed"):
            summary = generate_dataset(
                parse_scenario(scenario_dict()),
                out,
                scheduler=local.scheduler_address,
                on_frame_done=on_frame_done,
            )
    assert killed and summary.complete and summary.rendered == FRAME_COUNT
    assert "rendering it again" in caplog.text  # the lost frames were submitted again
    assert [r["frame_index"] for r in read_journal(out)] == list(range(FRAME_COUNT))
    assert file_hashes(out) == reference_hashes


def test_a_frame_lost_too_often_stops_the_run_and_resume_finishes_it(
    tmp_path: Path, reference_hashes, monkeypatch
) -> None:
    """With one attempt per frame the loss ends the run in one line; the committed frames
    are kept and --resume gives the single-process bytes."""
    monkeypatch.setattr(distributed, "MAX_FRAME_ATTEMPTS", 1)
    out = tmp_path / "dataset"
    with cluster() as local:

        def on_frame_done(done: int, total: int) -> None:
            if done == 2:
                kill_scenario_holders(local)

        with pytest.raises(SatsightError, match=r"was lost with its Dask worker 1 times.*--resume"):
            generate_dataset(
                parse_scenario(scenario_dict()),
                out,
                scheduler=local.scheduler_address,
                on_frame_done=on_frame_done,
            )
        committed = [r["frame_index"] for r in read_journal(out)]
        assert len(committed) >= 2 and not (out / "complete.json").exists()
        summary = generate_dataset(
            parse_scenario(scenario_dict()), out, resume=True, scheduler=local.scheduler_address
        )
    assert summary.complete and summary.committed_before == len(committed)
    assert file_hashes(out) == reference_hashes


# --- the dataset folder as the workers see it ----------------------------------------------
def test_a_relative_out_is_the_clients_folder_not_the_workers(
    tmp_path: Path, reference_hashes, monkeypatch
) -> None:
    """Workers started in another folder write into the client's ``out``, not their own."""
    elsewhere, here = tmp_path / "workers-folder", tmp_path / "client-folder"
    elsewhere.mkdir()
    here.mkdir()
    monkeypatch.chdir(elsewhere)  # the worker processes start here
    with cluster() as local:
        monkeypatch.chdir(here)
        summary = generate_dataset(
            parse_scenario(scenario_dict()), Path("out"), scheduler=local.scheduler_address
        )
    assert summary.complete
    assert list(elsewhere.iterdir()) == []
    assert file_hashes(here / "out") == reference_hashes


def _probe_into(monkeypatch, other: Path) -> None:
    """Workers whose path for the dataset folder names ``other`` (another disk: the folder
    is not shared): their probe files are written, and removed, there."""

    def write_other(folder: str, token: str, dask_worker=None):
        return _WRITE_PROBE(str(other), token, dask_worker=dask_worker)

    def remove_other(folder: str, token: str, dask_worker=None):
        return _REMOVE_PROBE(str(other), token, dask_worker=dask_worker)

    monkeypatch.setattr(distributed, "_write_probe", write_other)
    monkeypatch.setattr(distributed, "_remove_probe", remove_other)


def test_workers_that_cannot_write_the_folder_are_refused_before_anything_is_written(
    tmp_path: Path, monkeypatch
) -> None:
    other = tmp_path / "other-disk"
    other.mkdir()
    out = tmp_path / "out"
    scenario = parse_scenario(scenario_dict())
    with dask_distributed.LocalCluster(
        n_workers=1, processes=False, dashboard_address=":0"
    ) as local:
        _probe_into(monkeypatch, other)
        with pytest.raises(SatsightError, match=r"wrote into a folder .*/out that this machine"):
            generate_dataset(scenario, out, scheduler=local.scheduler_address)
        assert not out.exists()
        assert list(other.iterdir()) == []  # the worker's probe file is removed too
        _probe_into(monkeypatch, other / "missing")
        with pytest.raises(
            SatsightError, match=r"the Dask worker at .* cannot write into .*/out \(No such file"
        ):
            generate_dataset(scenario, out, scheduler=local.scheduler_address)
        assert not out.exists()
