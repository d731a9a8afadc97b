"""Local render processes (``satsight.run.processes``): when they start, that they make the
same bytes as one process, and how they end on a stop, a failing frame or a dead process."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

import process_frames
from cli_runner import run_satsight
from dataset_files import file_hashes, generated_dataset, views_scenario, write_scenario_yaml
from satsight.config.scenario import parse_scenario
from satsight.errors import SatsightError
from satsight.frame_memory import frame_memory_bytes
from satsight.run import processes
from satsight.run.generation import generate_dataset
from satsight.run.interrupt import StopFlag
from satsight.run.processes import (
    PROCESS_MAX_PIXELS,
    PROCESS_MIN_FRAMES,
    local_processes,
    run_processes,
)

GB = 1e9
VARIANT = "llvm_ad_rgb"


def _scenario() -> dict:
    return views_scenario("processes", 7, 6, (96, 72), 0.004, (41.0, 9, 40, 0.0), 3)


def test_processes_start_for_long_runs_of_small_frames_that_fit() -> None:
    auto = {"SATSIGHT_LOCAL_PROCESSES": "auto"}
    count, why = local_processes(1024, 1024, 201, cores=2, memory_bytes=20 * GB, environ=auto)
    assert count == 2 and "2 render processes" in why and "SATSIGHT_LOCAL_PROCESSES=1" in why
    assert local_processes(1024, 1024, 201, cores=8, memory_bytes=20 * GB, environ={})[0] == 8
    # One core, few frames, large frames: this process renders.
    assert local_processes(1024, 1024, 201, cores=1, memory_bytes=20 * GB, environ={}) == (1, None)
    few = PROCESS_MIN_FRAMES - 1
    assert local_processes(1024, 1024, few, cores=2, memory_bytes=20 * GB, environ={}) == (1, None)
    gpu = local_processes(1024, 1024, 201, 2, 20 * GB, {}, variant="cuda_ad_rgb")
    assert gpu == (1, None)
    side = int(PROCESS_MAX_PIXELS**0.5) + 1
    assert local_processes(side, side, 201, cores=2, memory_bytes=20 * GB, environ={})[0] == 1
    # Memory: this process's frame, then one kept-buffer frame per render process.
    own = frame_memory_bytes(1024, 1024, kept=False)
    each = frame_memory_bytes(1024, 1024, kept=True)
    fits_three = own + 3.5 * each
    assert local_processes(1024, 1024, 201, cores=8, memory_bytes=fits_three, environ={})[0] == 3
    tight = own + 1.5 * each
    assert local_processes(1024, 1024, 201, cores=8, memory_bytes=tight, environ={}) == (1, None)


def test_the_environment_sets_the_processes_or_fails_clearly() -> None:
    for text, count in (("1", 1), ("3", 3), (" 2 ", 2)):
        env = {"SATSIGHT_LOCAL_PROCESSES": text}
        assert local_processes(4096, 4112, 5, cores=1, memory_bytes=1.0, environ=env)[0] == count
    for bad in ("0", "-2", "two", "1.5"):
        with pytest.raises(SatsightError, match="SATSIGHT_LOCAL_PROCESSES"):
            local_processes(64, 64, 500, environ={"SATSIGHT_LOCAL_PROCESSES": bad})


def test_a_bad_request_fails_before_anything_is_written(tmp_path: Path, monkeypatch) -> None:
    scenario = parse_scenario(_scenario(), "processes")
    for bad in (0, "many", 1.5, True):
        with pytest.raises(SatsightError, match="render_processes"):
            generate_dataset(scenario, tmp_path / "a", render_processes=bad)
    monkeypatch.setenv("SATSIGHT_LOCAL_PROCESSES", "none")
    with pytest.raises(SatsightError, match="SATSIGHT_LOCAL_PROCESSES"):
        generate_dataset(scenario, tmp_path / "b", render_processes="auto")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_two_processes_write_the_bytes_of_one(tmp_path: Path) -> None:
    one = file_hashes(generated_dataset(tmp_path / "one", _scenario()))
    scenario = parse_scenario(_scenario(), "processes")
    summary = generate_dataset(scenario, tmp_path / "two", render_processes=2)
    assert summary.render_processes == 2 and summary.rendered == 6 and summary.complete
    assert sorted(summary.stage_seconds) == ["files", "render", "sensor"]
    assert all(len(times) == 6 for times in summary.stage_seconds.values())
    assert file_hashes(tmp_path / "two") == one


def _run(tmp_path: Path, monkeypatch, frame, todo, stop=None, on_commit=None) -> list[dict]:
    monkeypatch.setattr(processes, "make_frame", frame)
    committed: list[dict] = []

    def commit(record: dict) -> None:
        committed.append(record)
        if on_commit is not None:
            on_commit(len(committed))

    times: dict = {}
    scenario = {"kept": True}
    run_processes(VARIANT, scenario, tmp_path, todo, commit, stop or StopFlag(), times, 2)
    return committed


def test_processes_run_on_one_thread_each_and_ignore_ctrl_c(tmp_path, monkeypatch) -> None:
    monkeypatch.delenv("SATSIGHT_RENDER_THREADS", raising=False)
    before = signal.getsignal(signal.SIGINT)
    records = _run(tmp_path, monkeypatch, process_frames.reporting_frame, list(range(8)))
    assert all(r["scenario"] == {"kept": True} for r in records)  # handed over at the start
    assert sorted(r["frame_index"] for r in records) == list(range(8))
    assert len({r["pid"] for r in records}) <= 2
    assert all(r["sigint_ignored"] and r["render_threads"] == "1" for r in records)
    assert all(r["root"] == str(tmp_path.resolve()) and r["variant"] == "llvm_ad_rgb"
               for r in records)  # fmt: skip
    assert signal.getsignal(signal.SIGINT) is before  # this process's handler is back


def test_a_stop_commits_the_frames_in_flight_and_no_more(tmp_path, monkeypatch) -> None:
    stop = StopFlag()
    records = _run(
        tmp_path, monkeypatch, process_frames.reporting_frame, list(range(40)), stop,
        on_commit=lambda n: stop.set() if n == 3 else None,
    )  # fmt: skip
    # Four frames are in flight (two per process) when the third is committed.
    assert 3 <= len(records) <= 3 + 4
    assert len({r["frame_index"] for r in records}) == len(records)


def test_a_failing_frame_raises_after_the_others_in_flight(tmp_path, monkeypatch) -> None:
    # Frame 3 goes first and fails at once; frames 0-2, submitted beside it, take 0.3 s
    # each: they are still made and committed, and the run stops short of the rest.
    monkeypatch.setattr(processes, "make_frame", process_frames.failing_frame)
    records: list[dict] = []
    todo = [3, *range(3), *range(4, 20)]
    with pytest.raises(SatsightError, match="frame 3 cannot be made"):
        run_processes(VARIANT, {}, tmp_path, todo, records.append, StopFlag(), {}, 2)
    indices = {r["frame_index"] for r in records}
    assert {0, 1, 2} <= indices and 3 not in indices and len(indices) < 10


def test_a_dead_process_is_named(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(processes, "make_frame", process_frames.dying_frame)
    records: list[dict] = []
    todo = [*range(3), 3, *range(4, 20)]
    with pytest.raises(SatsightError) as raised:
        run_processes(VARIANT, {}, tmp_path, todo, records.append, StopFlag(), {}, 2)
    said = str(raised.value)
    assert "terminated abruptly" in said and "resume the run" in said
    assert "render process" in said and "was in flight" in said
    assert len(records) < len(todo) - 1


def test_processes_that_cannot_start_say_so(tmp_path, monkeypatch) -> None:
    # A process that ends at its start (here its set-up fails) gives the hint about the
    # calling script's __main__ guard, not the resume advice alone.
    monkeypatch.setattr(processes, "_start_process", process_frames.failing_start)
    with pytest.raises(SatsightError, match=r"before any frame came back .* guard"):
        run_processes(VARIANT, {}, tmp_path, list(range(4)), [].append, StopFlag(), {}, 2)


def test_the_command_says_it_rendered_in_processes(tmp_path: Path, monkeypatch) -> None:
    # ``python -m satsight generate``, render processes forced by the environment.
    scenario = write_scenario_yaml(tmp_path, _scenario())
    monkeypatch.setenv("SATSIGHT_LOCAL_PROCESSES", "2")
    done = run_satsight("generate", str(scenario), "--out", "ds", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    said = done.stdout + done.stderr  # (the console writes to standard error)
    assert "wrote 6 frames" in said and "llvm_ad_rgb in 2 render processes" in said
    checked = run_satsight("validate", "ds", cwd=tmp_path)
    assert checked.returncode == 0, checked.stdout + checked.stderr
