"""One writer per dataset folder: two real processes race for one folder, again and again;
exactly one writes, the other is refused with one line naming it, and the dataset
validates. Stale locks, Ctrl-C, errors and readers."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cli_runner import invoke_satsight, run_satsight
from dataset_files import generated_dataset, views_scenario, write_scenario_yaml
from satsight.config.scenario import parse_scenario
from satsight.dataset.journal import read_journal
from satsight.dataset.lock import LOCK_NAME, WriterLock
from satsight.dataset.validate import validate_dataset
from satsight.errors import SatsightError
from satsight.run.generation import generate_dataset

FRAME_COUNT = 10
REPEATS = 4
# Two at once: a third process, started later on a busy machine, can find the winner
# already done (a resume then says "already complete"), which is no race.
RACERS = 2


def scenario_dict() -> dict:
    return views_scenario(
        "concurrent-writers-test", 5, FRAME_COUNT, (128, 96), 0.002, (31.0, 13, 60, 5.0), 1
    )


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory) -> Path:
    return write_scenario_yaml(tmp_path_factory.mktemp("scenario"), scenario_dict())


@pytest.fixture(scope="module")
def complete_dataset(tmp_path_factory) -> Path:
    return generated_dataset(tmp_path_factory.mktemp("complete") / "dataset", scenario_dict())


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "satsight", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "COLUMNS": "400"},
    )


def _race(*args: str) -> list[tuple[int, int, str]]:
    """Start the same command RACERS times at once; (pid, exit status, stderr) of each."""
    processes = [_start(*args) for _ in range(RACERS)]
    results = []
    for process in processes:
        _, stderr = process.communicate(timeout=300)
        results.append((process.pid, process.returncode, stderr))
    return results


def _one_wins(results: list[tuple[int, int, str]], out: Path) -> None:
    """Exactly one run succeeded; every other exited 2 with one line naming the winner."""
    statuses = sorted(status for _, status, _ in results)
    assert statuses == [0] + [2] * (RACERS - 1), results
    (winner,) = [pid for pid, status, _ in results if status == 0]
    for stderr in [err for _, status, err in results if status == 2]:
        assert "Traceback" not in stderr
        errors = [line for line in stderr.splitlines() if line.startswith("error: ")]
        assert len(errors) == 1, stderr
        assert re.search(
            rf"{re.escape(str(out))} is being written by another satsight process \(pid "
            rf"{winner} on {re.escape(socket.gethostname())}, since \S+: satsight generate ",
            errors[0],
        ), errors[0]
    report = validate_dataset(out)
    assert report.ok, [str(p) for p in report.findings.problems]
    assert len(read_journal(out)) == FRAME_COUNT
    assert not (out / LOCK_NAME).exists()


@pytest.mark.parametrize("repeat", range(REPEATS))
def test_overwrites_of_a_complete_dataset_all_but_one_are_refused(
    tmp_path: Path, scenario_file: Path, complete_dataset: Path, repeat: int
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(complete_dataset, out)
    results = _race("generate", scenario_file, "--out", out, "--overwrite")
    _one_wins(results, out)


@pytest.mark.parametrize("repeat", range(REPEATS))
def test_resumes_of_an_incomplete_dataset_all_but_one_are_refused(
    tmp_path: Path, scenario_file: Path, complete_dataset: Path, repeat: int
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(complete_dataset, out)
    for name in ("complete.json", "labels.json", "contact_sheet.png"):
        (out / name).unlink()
    lines = (out / "journal.jsonl").read_bytes().splitlines(keepends=True)
    (out / "journal.jsonl").write_bytes(b"".join(lines[:2]))  # 2 of 10 frames committed
    results = _race("generate", scenario_file, "--out", out, "--resume")
    _one_wins(results, out)


#: Races of new runs tried until the second process starts while the first still writes.
NEW_RUN_ATTEMPTS = 5


@pytest.mark.parametrize("repeat", range(2))
def test_new_runs_into_one_folder_all_but_one_are_refused(
    tmp_path: Path, scenario_file: Path, repeat: int
) -> None:
    """On a busy machine the second process can start after the first has finished; it is
    then refused for another reason (the folder holds a complete dataset), which is right
    but no race: the folder is emptied and the race run again."""
    out = tmp_path / "dataset"
    for _ in range(NEW_RUN_ATTEMPTS):
        results = _race("generate", scenario_file, "--out", out)
        late = [err for _, status, err in results if status == 2 and "holds a complete" in err]
        if not late:
            break
        assert sorted(status for _, status, _ in results) == [0, 2], results
        assert "pass --overwrite to replace it" in late[0]
        shutil.rmtree(out)
    _one_wins(results, out)


# --- stale locks --------------------------------------------------------------------------
def _dead_pid() -> int:
    """The id of a process of this machine that has ended."""
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def _write_lock(folder: Path, pid: int, host: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    holder = {"pid": pid, "host": host, "started": "2024-01-01T00:00:00+0000",
              "command": "satsight generate old.yaml --out x"}  # fmt: skip
    (folder / LOCK_NAME).write_text(json.dumps(holder) + "\n", encoding="utf-8")


def test_a_stale_lock_of_this_machine_is_taken_over_with_a_note(
    tmp_path: Path, scenario_file: Path, complete_dataset: Path
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(complete_dataset, out)
    (out / "complete.json").unlink()
    pid = _dead_pid()
    _write_lock(out, pid, socket.gethostname())
    done = invoke_satsight("generate", str(scenario_file), "--out", str(out), "--resume",
                           cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "taking over the lock of an earlier writer" in done.stderr
    assert f"pid {pid} on {socket.gethostname()}" in done.stderr
    assert validate_dataset(out).ok and not (out / LOCK_NAME).exists()


def test_a_lock_file_of_another_machine_is_refused_and_kept(
    tmp_path: Path, scenario_file: Path, complete_dataset: Path
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(complete_dataset, out)
    _write_lock(out, 4242, "render-node-7")
    lock_text = (out / LOCK_NAME).read_text(encoding="utf-8")
    refused = invoke_satsight("generate", str(scenario_file), "--out", str(out), "--overwrite",
                              cwd=tmp_path)  # fmt: skip
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert "names a writer on render-node-7" in refused.stderr
    assert "delete the lock file" in refused.stderr
    assert (out / LOCK_NAME).read_text(encoding="utf-8") == lock_text
    assert (out / "complete.json").is_file()


def test_a_lock_file_left_in_a_new_folder_does_not_make_it_a_foreign_folder(
    tmp_path: Path,
) -> None:
    out = tmp_path / "dataset"
    _write_lock(out, _dead_pid(), socket.gethostname())
    assert generate_dataset(parse_scenario(scenario_dict()), out).complete
    assert not (out / LOCK_NAME).exists()


# --- release ------------------------------------------------------------------------------
def test_ctrl_c_releases_the_lock(tmp_path: Path, scenario_file: Path) -> None:
    out = tmp_path / "dataset"
    process = _start("generate", scenario_file, "--out", out)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and process.poll() is None:
        journal = out / "journal.jsonl"
        if journal.is_file() and journal.read_bytes().count(b"\n") >= 2:
            break
        time.sleep(0.005)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert not (out / LOCK_NAME).exists()
    resumed = invoke_satsight("generate", str(scenario_file), "--out", str(out), "--resume",
                              cwd=tmp_path)  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert validate_dataset(out).ok


def test_an_error_releases_the_lock(tmp_path: Path, monkeypatch) -> None:
    import satsight.run.generation as generation

    def fail(*args, **kwargs):
        raise SatsightError("a failure in the middle of the run")

    monkeypatch.setattr(generation, "run_local", fail)
    out = tmp_path / "dataset"
    with pytest.raises(SatsightError, match="a failure in the middle"):
        generate_dataset(parse_scenario(scenario_dict()), out)
    assert (out / "manifest.json").is_file() and not (out / LOCK_NAME).exists()


def test_a_second_writer_in_the_same_process_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    with WriterLock(out):
        with pytest.raises(SatsightError, match=rf"pid {os.getpid()} on"):
            generate_dataset(parse_scenario(scenario_dict()), out)
        assert (out / LOCK_NAME).is_file() and not (out / "manifest.json").exists()
    assert not out.exists()  # the lock created the folder and leaves it as it found it


# --- readers ------------------------------------------------------------------------------
def test_readers_do_not_need_the_lock(tmp_path: Path, complete_dataset: Path) -> None:
    with WriterLock(complete_dataset):
        checked = run_satsight("validate", str(complete_dataset), cwd=tmp_path)
        assert checked.returncode == 0, checked.stdout + checked.stderr
        counted = run_satsight("stats", str(complete_dataset), "--out", str(tmp_path / "s"),
                               cwd=tmp_path)  # fmt: skip
        assert counted.returncode == 0, counted.stderr
    assert not (complete_dataset / LOCK_NAME).exists()
