"""Datasets written frame by frame: resume after kill -9 or Ctrl-C, shards, Dask workers,
output profiles and crops, all checked against an uninterrupted run byte for byte."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from cli_runner import invoke_satsight
from dataset_files import file_hashes, write_scenario_yaml
from figure_checks import figure_pixels
from satsight.config.scenario import parse_scenario
from satsight.dataset.image_files import exr_channels, read_exr, read_png
from satsight.dataset.journal import read_journal
from satsight.dataset.merge import merge_shards
from satsight.dataset.preview import PreviewStretch, dn_preview_uint8
from satsight.dataset.reader import open_dataset
from satsight.dataset.validate import validate_dataset
from satsight.errors import SatsightError
from satsight.run.generation import generate_dataset
from satsight.run.interrupt import StopFlag
from satsight.run.shard import Shard

FRAME_COUNT = 12
WIDTH_PX, HEIGHT_PX = 128, 96
CROP_PX = 40


def scenario_dict(**outputs) -> dict:
    frames = [
        {
            "distance_km": 0.03 + 0.002 * i,
            "azimuth_deg": 29.0 * i,
            "elevation_deg": (i * 13) % 80 - 40,
            "roll_deg": 7.0 * i,
        }
        for i in range(FRAME_COUNT - 1)
    ]
    frames.append({"distance_km": 50.0, "azimuth_deg": 10, "elevation_deg": 5, "roll_deg": 0})
    return {
        "name": "generation-test",
        "seed": 7,
        "camera": {"preset": "wide_field", "width_px": WIDTH_PX, "height_px": HEIGHT_PX},
        "target": {"procedural": {"satellite_class": "two_wings", "seed": 1}},
        "earth": {"azimuth_deg": 200, "elevation_deg": -60, "altitude_km": 500},
        "frames": frames,
        "render": {"bounces": 1},
        "outputs": {"crop": {"size_px": CROP_PX}, **outputs},
    }


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory) -> Path:
    return write_scenario_yaml(tmp_path_factory.mktemp("scenario"), scenario_dict())


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The dataset of an uninterrupted run in this process."""
    out = tmp_path_factory.mktemp("reference") / "dataset"
    summary = generate_dataset(parse_scenario(scenario_dict()), out)
    assert summary.complete and summary.rendered == FRAME_COUNT
    return out


@pytest.fixture(scope="module")
def reference_hashes(reference: Path) -> dict[str, str]:
    return file_hashes(reference)


# --- the folder ---------------------------------------------------------------------------
def test_every_frame_is_in_the_journal_with_its_checksums(reference: Path) -> None:
    dataset = open_dataset(reference)
    assert dataset.complete and dataset.frame_count == FRAME_COUNT
    assert [r["frame_index"] for r in read_journal(reference)] == list(range(FRAME_COUNT))
    for frame in dataset.frames:
        paths = set(frame["files"].values()) | set(frame["crop"]["files"].values())
        assert set(frame["checksums"]) == paths
        for relative, checksum in frame["checksums"].items():
            data = (reference / relative).read_bytes()
            assert len(data) == checksum["size_bytes"]
            assert hashlib.sha256(data).hexdigest() == checksum["sha256"]
    complete = json.loads((reference / "complete.json").read_text(encoding="utf-8"))
    labels = (reference / "labels.json").read_bytes()
    assert complete["labels_sha256"] == hashlib.sha256(labels).hexdigest()


def test_a_second_run_writes_the_same_bytes(tmp_path: Path, reference_hashes) -> None:
    generate_dataset(parse_scenario(scenario_dict()), tmp_path / "again")
    assert file_hashes(tmp_path / "again") == reference_hashes


def test_an_incomplete_dataset_is_refused_by_readers(tmp_path: Path, reference: Path) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(reference, copy)
    (copy / "complete.json").unlink()
    with pytest.raises(SatsightError, match=r"incomplete dataset.*--resume"):
        open_dataset(copy)
    partial = open_dataset(copy, require_complete=False)
    assert not partial.complete and len(partial.frames) == FRAME_COUNT


# --- resume -------------------------------------------------------------------------------
def _start(scenario_file: Path, out: Path, *extra: str) -> subprocess.Popen:
    """``satsight generate`` in a process group of its own (as a shell starts a job)."""
    return subprocess.Popen(
        [sys.executable, "-m", "satsight", "generate", str(scenario_file), "--out", str(out),
         *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "COLUMNS": "200"},
        start_new_session=True,
    )  # fmt: skip


def _wait_for_commits(out: Path, count: int, process: subprocess.Popen) -> int:
    """Wait until the journal holds ``count`` lines (or the run ends); the lines seen."""
    journal = out / "journal.jsonl"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and process.poll() is None:
        if journal.is_file() and journal.read_bytes().count(b"\n") >= count:
            break
        time.sleep(0.005)
    return journal.read_bytes().count(b"\n") if journal.is_file() else 0


def _resume_gives(reference_hashes: dict, out: Path, cwd: Path, *args: str) -> None:
    """Run ``satsight ARGS``; it must succeed and leave ``out`` equal to the reference.

    The command runs in this interpreter (the renderer's kernels are compiled here
    already): what is under test is the folder the killed or stopped child process left,
    and the command's own code, which is the same in either process."""
    resumed = invoke_satsight(*args, cwd=cwd)
    assert resumed.returncode == 0, resumed.stderr
    assert file_hashes(out) == reference_hashes


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kill_9_at_a_random_moment_then_resume_gives_the_same_bytes(
    tmp_path: Path, scenario_file: Path, reference_hashes, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    commits, delay_s = int(rng.integers(1, FRAME_COUNT - 2)), float(rng.uniform(0, 0.05))
    out = tmp_path / "dataset"
    process = _start(scenario_file, out)
    _wait_for_commits(out, commits, process)
    time.sleep(delay_s)
    process.send_signal(signal.SIGKILL)
    process.communicate()
    assert not (out / "complete.json").exists()
    refused = invoke_satsight("generate", str(scenario_file), "--out", str(out), cwd=tmp_path)
    assert refused.returncode == 2 and "--resume" in refused.stderr
    _resume_gives(reference_hashes, out, tmp_path, "generate", str(scenario_file), "--out",
                  str(out), "--resume")  # fmt: skip


# One Dask worker process: the signal reaches it as it would reach any number of them.
# "processes": two local render processes (SATSIGHT_LOCAL_PROCESSES), resumed with them too.
@pytest.mark.parametrize("workers", [None, "1", "processes"])
def test_ctrl_c_stops_after_the_frame_in_flight_and_says_how_to_resume(
    tmp_path: Path, scenario_file: Path, reference_hashes, workers: str | None, monkeypatch
) -> None:
    """Ctrl-C in a terminal reaches the whole job (the process group): Dask's worker
    processes and render processes too, which ignore it, so the run still stops cleanly."""
    if workers == "processes":
        monkeypatch.setenv("SATSIGHT_LOCAL_PROCESSES", "2")
        workers = None
    elif workers is not None:
        pytest.importorskip("dask.distributed")
    out = tmp_path / "dataset"
    process = _start(scenario_file, out, *(() if workers is None else ("--workers", workers)))
    _wait_for_commits(out, 3, process)
    os.killpg(process.pid, signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr
    committed = len(read_journal(out))
    assert 3 <= committed < FRAME_COUNT
    assert f"{committed} of {FRAME_COUNT} frames committed" in stderr
    assert "--resume" in stderr
    # Every committed frame's files are whole; nothing is left under a temporary name.
    assert not [p for p in out.rglob(".*") if ".tmp-" in p.name]
    dataset = open_dataset(out, require_complete=False)
    for frame in dataset.frames:
        for relative, checksum in frame["checksums"].items():
            assert (out / relative).stat().st_size == checksum["size_bytes"]
    # The command the message gives is the one that finishes the dataset.
    command = " ".join(stderr.split()).split("resume with: satsight ", 1)[1]
    _resume_gives(reference_hashes, out, tmp_path, *shlex.split(command))


def test_resume_drops_a_torn_journal_line_and_redoes_frames_with_missing_files(
    tmp_path: Path, reference: Path, reference_hashes
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(reference, out)
    for name in ("complete.json", "labels.json", "contact_sheet.png"):
        (out / name).unlink()
    lines = (out / "journal.jsonl").read_bytes().splitlines(keepends=True)
    (out / "journal.jsonl").write_bytes(b"".join(lines[:7]) + lines[7][:40])  # torn line 8
    (out / "depth" / "frame_000002.exr").unlink()
    (out / "images" / "frame_000004.png").write_bytes(b"\x89PNG cut")
    (out / "images" / ".frame_000009.png.tmp-1234").write_bytes(b"half")
    summary = generate_dataset(parse_scenario(scenario_dict()), out, resume=True)
    assert summary.committed_before == 5  # frames 0, 1, 3, 5, 6
    assert summary.rendered == FRAME_COUNT - 5
    assert file_hashes(out) == reference_hashes


def test_resume_refuses_another_scenario_naming_what_differs(
    tmp_path: Path, reference: Path
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(reference, out)
    (out / "complete.json").unlink()
    before = file_hashes(out)
    other = scenario_dict()
    other["seed"] = 8
    with pytest.raises(SatsightError, match=r"another scenario \(differs in seed\)"):
        generate_dataset(parse_scenario(other), out, resume=True)
    assert file_hashes(out) == before


def test_resume_of_a_complete_dataset_changes_nothing(tmp_path: Path, reference: Path) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(reference, out)
    before = file_hashes(out)
    summary = generate_dataset(parse_scenario(scenario_dict()), out, resume=True)
    assert summary.complete and summary.rendered == 0
    assert file_hashes(out) == before


@pytest.mark.parametrize("in_flight", [1, 2])
def test_a_stop_flag_ends_the_run_after_the_frame_in_flight(
    tmp_path: Path, reference_hashes, monkeypatch, in_flight: int
) -> None:
    """Stopped after its second commit, a run commits the frames in flight (none more with
    one frame at a time) and stops; --resume finishes it with the bytes of an
    uninterrupted run."""
    from satsight.run import generation

    monkeypatch.setattr(generation, "frames_in_flight", lambda width, height: (in_flight, None))
    stop = StopFlag()

    def on_frame_done(done: int, total: int) -> None:
        if done == 2:
            stop.set()

    summary = generate_dataset(
        parse_scenario(scenario_dict()), tmp_path / "d", on_frame_done=on_frame_done, stop=stop
    )
    assert summary.interrupted and not summary.complete
    # The frame rendering when the flag was set, and the one being finished, commit.
    assert 2 <= summary.rendered <= 2 + in_flight
    if in_flight == 1:
        assert summary.rendered == 2
    assert not (tmp_path / "d" / "complete.json").exists()
    resumed = generate_dataset(parse_scenario(scenario_dict()), tmp_path / "d", resume=True)
    assert resumed.complete and resumed.rendered == FRAME_COUNT - summary.rendered
    assert file_hashes(tmp_path / "d") == reference_hashes


def test_disk_full_names_the_path_keeps_committed_frames_and_resume_finishes(
    tmp_path: Path, reference_hashes, monkeypatch
) -> None:
    import satsight.dataset.frame_files as frame_files

    real_replace = os.replace
    failing = {"frame_000005"}

    def replace(source, target):
        if any(stem in str(target) for stem in failing):
            raise OSError(errno.ENOSPC, "No space left on device", str(target))
        return real_replace(source, target)

    monkeypatch.setattr(frame_files.os, "replace", replace)
    out = tmp_path / "dataset"
    with pytest.raises(SatsightError, match=r"could not write .*frame_000005.*--resume"):
        generate_dataset(parse_scenario(scenario_dict()), out)
    committed = {r["frame_index"] for r in read_journal(out)}
    assert set(range(5)) <= committed and 5 not in committed
    assert not [p for p in out.rglob(".*") if ".tmp-" in p.name]
    failing.clear()  # space freed
    generate_dataset(parse_scenario(scenario_dict()), out, resume=True)
    assert file_hashes(out) == reference_hashes


# --- shards and workers -------------------------------------------------------------------
def test_shards_merged_give_the_same_bytes(tmp_path: Path, reference_hashes) -> None:
    scenario = parse_scenario(scenario_dict())
    shards = []
    for k in range(3):
        folder = tmp_path / f"shard{k}"
        summary = generate_dataset(scenario, folder, shard=Shard(k, 3))
        assert summary.complete and summary.frame_count == len(range(k, FRAME_COUNT, 3))
        shards.append(folder)
    with pytest.raises(SatsightError, match="not each of"):
        merge_shards(shards[:2], tmp_path / "missing-one")
    assert not (tmp_path / "missing-one").exists()
    merge_shards(shards, tmp_path / "merged")
    assert file_hashes(tmp_path / "merged") == reference_hashes


def test_shards_of_different_scenarios_are_refused(tmp_path: Path) -> None:
    one = generate_dataset(parse_scenario(scenario_dict()), tmp_path / "a", shard=Shard(0, 2))
    other = scenario_dict()
    other["seed"] = 99
    two = generate_dataset(parse_scenario(other), tmp_path / "b", shard=Shard(1, 2))
    assert one.complete and two.complete
    with pytest.raises(SatsightError, match="another scenario"):
        merge_shards([tmp_path / "a", tmp_path / "b"], tmp_path / "merged")


def test_bad_shard_option_is_a_clear_error() -> None:
    for text in ("3/2", "0/4", "one/two", "1"):
        with pytest.raises(SatsightError, match="--shard"):
            Shard.parse(text)


def test_dask_workers_give_the_same_bytes(tmp_path: Path, scenario_file: Path, reference_hashes):
    """``--workers 2``: the frames are split between two worker processes, each with an
    engine of its own, and the bytes are the single-process run's. One worker takes the
    same path (the scattered scenario, the task, the files written by the worker) without
    the split, so two prove it too. The command runs in this interpreter; its workers are
    processes of their own either way."""
    pytest.importorskip("dask.distributed")
    out = tmp_path / "workers2"
    result = invoke_satsight(
        "generate", str(scenario_file), "--out", str(out), "--workers", "2", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert file_hashes(out) == reference_hashes


def test_workers_on_a_small_machine_render_in_one_process(
    tmp_path: Path, scenario_file: Path, reference_hashes, monkeypatch
) -> None:
    """``--workers 2`` where one process keeps the cores busy (fewer than 2 x 2 cores, as
    here): a line saying why, no Dask cluster, the same bytes; with 4 cores or more the
    workers start, one per 2 cores (``local_workers``), and SATSIGHT_LOCAL_WORKERS=always
    starts them anyway."""
    from satsight.run import distributed

    monkeypatch.delenv("SATSIGHT_LOCAL_WORKERS", raising=False)
    assert distributed.local_workers(2, cores=4) == (2, None)
    assert distributed.local_workers(8, cores=16) == (8, None)
    count, why = distributed.local_workers(4, cores=4)  # 2 cores each: 2 of the 4
    assert count == 2 and why.startswith("--workers 4: starting 2, 2 cores each on 4 cores")
    assert distributed.local_workers(1, cores=16)[0] is None  # one worker: never worth it
    count, why = distributed.local_workers(2, cores=2)
    assert count is None
    assert why.startswith("--workers 2: rendering in this process instead; on 2 cores")
    started = []
    monkeypatch.setattr(distributed, "dask_client", lambda *a, **k: started.append(a))
    monkeypatch.setattr(distributed, "machine_cores", lambda: 2)
    out = tmp_path / "one-process"
    result = invoke_satsight(
        "generate", str(scenario_file), "--out", str(out), "--workers", "2", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert "--workers 2: rendering in this process instead" in result.stderr
    assert not started
    assert file_hashes(out) == reference_hashes
    monkeypatch.setenv("SATSIGHT_LOCAL_WORKERS", "always")
    assert distributed.local_workers(2, cores=2) == (2, None)


def test_a_memory_limit_makes_frames_one_at_a_time_with_the_same_bytes(
    tmp_path: Path, scenario_file: Path, reference_hashes, monkeypatch
) -> None:
    """With memory for one frame in flight but not two (``--memory-gb``, or
    ``SATSIGHT_MEMORY_LIMIT_GB``), the run says so and makes its frames one at a time:
    each render's freed buffers and the freed heap are handed back before the next stage,
    and the bytes are the same."""
    from satsight import frame_memory
    from satsight.run import local

    one = frame_memory.frame_memory_bytes(WIDTH_PX, HEIGHT_PX)
    two = frame_memory.frame_memory_bytes(WIDTH_PX, HEIGHT_PX, frame_memory.PIPELINED_FRAMES)
    assert one < two
    between = f"{(one + two) / 2 / 1e9:.7f}"
    assert one < float(between) * 1e9 < two
    calls: list[str] = []
    monkeypatch.setattr(local, "release_render_memory", lambda variant: calls.append("render"))
    monkeypatch.setattr(local, "return_freed_heap", lambda: calls.append("heap"))
    monkeypatch.delenv(frame_memory.MEMORY_LIMIT_VARIABLE, raising=False)
    out = tmp_path / "one-at-a-time"
    result = invoke_satsight(
        "generate", str(scenario_file), "--out", str(out), "--memory-gb", between, cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    message = " ".join(result.stderr.split())
    assert f"frames are made one at a time: 2 in flight at {WIDTH_PX} x {HEIGHT_PX} px" in message
    assert f"{float(between):.1f} GB is available" in message
    assert calls == ["render", "heap"] * FRAME_COUNT
    assert file_hashes(out) == reference_hashes
    assert frame_memory.MEMORY_LIMIT_VARIABLE not in os.environ  # put back after the run
    # The variable does the same; with room for two, no line and nothing handed back.
    monkeypatch.setenv(frame_memory.MEMORY_LIMIT_VARIABLE, between)
    assert frame_memory.frames_in_flight(WIDTH_PX, HEIGHT_PX)[0] == 1
    monkeypatch.setenv(frame_memory.MEMORY_LIMIT_VARIABLE, f"{two / 1e9 + 1e-6:.7f}")
    calls.clear()
    result = invoke_satsight("generate", str(scenario_file), "--out", str(tmp_path / "two"),
                             cwd=tmp_path)  # fmt: skip
    assert result.returncode == 0 and "one at a time" not in result.stderr
    assert calls == []
    assert file_hashes(tmp_path / "two") == reference_hashes
    result = invoke_satsight("generate", str(scenario_file), "--out", str(tmp_path / "bad"),
                             "--memory-gb", "0", cwd=tmp_path)  # fmt: skip
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "--memory-gb" in result.stderr and not (tmp_path / "bad").exists()
    for bad in ("nan", "inf"):
        result = invoke_satsight("generate", str(scenario_file), "--out", str(tmp_path / "bad"),
                                 "--memory-gb", bad, cwd=tmp_path)  # fmt: skip
        assert result.returncode == 2 and "Traceback" not in result.stderr, bad
        assert "not a finite number of GB" in result.stderr and not (tmp_path / "bad").exists()


def test_one_cpu_gives_the_same_bytes(tmp_path: Path, scenario_file: Path, reference_hashes):
    """Under ``taskset -c 0`` the sensor's noise runs on one thread, the renderer on one
    core: the bytes do not depend on the thread count."""
    taskset = shutil.which("taskset")
    if taskset is None:
        pytest.skip("taskset is not installed")
    out = tmp_path / "one-cpu"
    result = subprocess.run(
        [taskset, "-c", "0", sys.executable, "-m", "satsight", "generate", str(scenario_file),
         "--out", str(out)],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert file_hashes(out) == reference_hashes


# --- output profiles and crops ------------------------------------------------------------
def test_lean_outputs_write_dn_and_masks_only_with_the_same_labels(
    tmp_path: Path, reference: Path
) -> None:
    out = tmp_path / "lean"
    scenario = parse_scenario(scenario_dict(files=["dn", "masks"]))
    generate_dataset(scenario, out)
    lean, full = open_dataset(out), open_dataset(reference)
    for a, b in zip(lean.frames, full.frames, strict=True):
        assert set(a["files"]) == {
            "dn_png16",
            "object_mask_png",
            "part_mask_png16",
            "background_mask_png",
        }
        for key in a["files"]:
            assert (out / a["files"][key]).read_bytes() == (
                reference / b["files"][key]
            ).read_bytes()
        strip = ("files", "checksums", "crop")
        assert {k: v for k, v in a.items() if k not in strip} == {
            k: v for k, v in b.items() if k not in strip
        }
    assert not (out / "radiance").exists() and not (out / "depth").exists()


def test_crop_files_are_the_full_frame_cut_with_shifted_intrinsics(reference: Path) -> None:
    dataset = open_dataset(reference)
    for frame in dataset.frames:
        crop = frame["crop"]
        x0, y0, x1, y1 = crop["box_xyxy_px"]
        assert (x1 - x0, y1 - y0) == (CROP_PX, CROP_PX) == (crop["size_px"],) * 2
        assert 0 <= x0 and x1 <= WIDTH_PX and 0 <= y0 and y1 <= HEIGHT_PX
        full_dn = read_png(dataset.path(frame, "dn_png16"))
        crop_dn = read_png(dataset.path(frame, "dn_png16", crop=True))
        np.testing.assert_array_equal(crop_dn, full_dn[y0:y1, x0:x1])
        full_depth = read_exr(dataset.path(frame, "depth_exr"))["Z"]
        crop_depth = read_exr(dataset.path(frame, "depth_exr", crop=True))["Z"]
        np.testing.assert_array_equal(crop_depth, full_depth[y0:y1, x0:x1])
        K, Kc = np.array(frame["K"]), np.array(crop["K"])
        np.testing.assert_array_equal(Kc[:, :2], K[:, :2])
        assert (Kc[0, 2], Kc[1, 2]) == (K[0, 2] - x0, K[1, 2] - y0)
        # The target's box centre projects at the crop's centre pixel unless the crop was
        # shifted inward at the image border.
        for axis, extent in ((0, WIDTH_PX), (1, HEIGHT_PX)):
            full = frame["box_keypoints_px"][-1][axis]
            if CROP_PX // 2 <= np.floor(full + 0.5) <= extent - CROP_PX // 2:
                assert np.floor(crop["box_keypoints_px"][-1][axis] + 0.5) == CROP_PX // 2
        mask = read_png(dataset.path(frame, "object_mask_png", crop=True)) > 0
        assert int(mask.sum()) == crop["object_pixel_count"]


# --- previews and photometric labels ------------------------------------------------------
def test_previews_take_the_scenarios_stretch_and_the_manifest_names_it(
    tmp_path: Path, reference: Path
) -> None:
    """asinh by default (the DN images are the same whatever the stretch); gamma on demand,
    byte for byte the gamma stretch of the DN."""
    gamma_out = tmp_path / "gamma"
    generate_dataset(
        parse_scenario(scenario_dict(files=["dn", "preview"], preview_stretch="gamma")),
        gamma_out,
    )
    for root, name in ((reference, "asinh"), (gamma_out, "gamma")):
        dataset = open_dataset(root)
        entry = dataset.header["preview"]
        assert entry["stretch"] == name and entry["formula"]
        stretch = PreviewStretch.from_header(entry)
        assert stretch.name == name
        detector = dataset.header["sensor"]["detector"]
        bias = detector["bias_dn"]
        full_well = bias + detector["full_well_e"] / detector["conversion_gain_e_per_dn"]
        for frame in dataset.frames:
            dn = read_png(dataset.path(frame, "dn_png16"))
            preview = read_png(dataset.path(frame, "preview_png8"))
            np.testing.assert_array_equal(preview, stretch.apply(dn, bias, full_well))
            if name == "gamma":
                np.testing.assert_array_equal(preview, dn_preview_uint8(dn, bias, full_well))
                reference_dn = reference / frame["files"]["dn_png16"]
                assert reference_dn.read_bytes() == dataset.path(frame, "dn_png16").read_bytes()
    assert validate_dataset(gamma_out).ok


def test_exr_files_take_the_scenarios_compression_with_the_same_values(
    tmp_path: Path, reference: Path
) -> None:
    """outputs.exr_compression: Zstandard EXRs hold the same values, bit for bit, as the
    default RLE ones (the PNGs are the same files); the header names it, the files' own
    headers carry it, and validate accepts the dataset."""
    import OpenEXR

    out = tmp_path / "zstd"
    generate_dataset(parse_scenario(scenario_dict(exr_compression="zstd")), out)
    dataset, default = open_dataset(out), open_dataset(reference)
    assert dataset.header["outputs"]["exr_compression"] == "zstd"
    assert default.header["outputs"]["exr_compression"] == "rle"
    for frame, reference_frame in zip(dataset.frames, default.frames, strict=True):
        for key in ("radiance_exr", "depth_exr", "normals_exr"):
            path = dataset.path(frame, key)
            with OpenEXR.File(str(path), header_only=True) as exr:
                assert exr.header()["compression"] == OpenEXR.ZSTD_COMPRESSION
            ours, theirs = exr_channels(path), exr_channels(default.path(reference_frame, key))
            assert ours.keys() == theirs.keys()
            for name, values in ours.items():
                np.testing.assert_array_equal(values.view(np.uint32), theirs[name].view(np.uint32))
        for key in ("dn_png16", "part_mask_png16"):
            assert (
                dataset.path(frame, key).read_bytes()
                == default.path(reference_frame, key).read_bytes()
            )
    assert validate_dataset(out).ok


def test_frames_carry_the_targets_irradiance_and_v_magnitude(reference: Path) -> None:
    """target_irradiance_w_m2 is the sum of the in-band radiance (radiance EXR) times
    (p / f)^2 cos^3(theta): over the whole frame where nothing but the target is drawn (the
    near frames, which it fills), over the object mask grown by one pixel where the Earth
    fills the rest (the 50 km frame); the magnitude is -26.76 - 2.5 log10(E / E_sun) with
    the Sun at 1 AU; validate accepts the fields."""
    dataset = open_dataset(reference)
    header = dataset.header
    weights = np.array(header["sensor"]["channel_weights_rgb"])
    K = np.array(header["camera"]["K"])
    p_over_f = header["camera"]["pixel_pitch_m"] / header["camera"]["focal_length_m"]
    v, u = np.mgrid[0:HEIGHT_PX, 0:WIDTH_PX]
    cos3 = (1.0 + ((u - K[0, 2]) / K[0, 0]) ** 2 + ((v - K[1, 2]) / K[1, 1]) ** 2) ** -1.5
    magnitudes = {}
    for frame in dataset.frames:
        radiance = read_exr(dataset.path(frame, "radiance_exr"))["RGB"].astype(np.float64)
        mask = read_png(dataset.path(frame, "object_mask_png")) > 0
        band = radiance @ weights
        summed = np.ones(mask.shape, dtype=bool)
        if (band[~mask] > 0).any():  # the Earth behind the target, all around it
            assert (band[~mask] > 0).all()
            corners = np.array(frame["box_keypoints_px"][:8])
            x0, y0 = np.floor(corners.min(axis=0) + 0.5).astype(int)
            x1, y1 = np.floor(corners.max(axis=0) + 0.5).astype(int) + 1
            summed = binary_dilation(mask, structure=np.ones((3, 3), dtype=bool))
            summed[:, :x0] = summed[:, x1:] = summed[:y0] = summed[y1:] = False
            assert summed.sum() > mask.sum() > 0
        expected = float(np.sum(np.where(summed, band, 0.0) * cos3)) * p_over_f**2
        assert frame["target_irradiance_w_m2"] == pytest.approx(expected, rel=1e-5)
        magnitude = -26.76 - 2.5 * np.log10(expected / frame["sun_irradiance_w_m2"])
        assert frame["target_v_magnitude_equivalent"] == pytest.approx(magnitude, abs=1e-5)
        magnitudes[frame["range_m"]] = frame["target_v_magnitude_equivalent"]
    far = max(magnitudes)
    assert far == pytest.approx(50e3, rel=0.01)
    assert magnitudes[far] > max(m for r, m in magnitudes.items() if r < far)
    assert validate_dataset(reference).ok


def test_crop_only_dataset_has_no_full_frame_files(tmp_path: Path) -> None:
    out = tmp_path / "crops"
    generate_dataset(parse_scenario(scenario_dict(crop={"size_px": 32, "full_frame": False})), out)
    dataset = open_dataset(out)
    for frame in dataset.frames:
        assert frame["files"] == {}
        assert set(frame["checksums"]) == set(frame["crop"]["files"].values())
    assert not (out / "images").exists()
    figure_pixels(out / "contact_sheet.png")  # an RGB PNG with the crops on it, not blank


def test_outputs_option_and_crop_larger_than_the_image_are_refused(
    tmp_path: Path, scenario_file: Path
) -> None:
    result = invoke_satsight(
        "generate", str(scenario_file), "--out", str(tmp_path / "x"), "--outputs", "dn,exr",
        cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 2 and "unknown output exr" in result.stderr
    result = invoke_satsight(
        "generate", str(scenario_file), "--out", str(tmp_path / "x"), "--crop-px", "500",
        cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 2 and "outputs.crop.size_px (500) exceeds" in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "x").exists()


def test_an_existing_scheduler_and_a_worker_killed_mid_run(tmp_path: Path, reference_hashes):
    """``--scheduler``: frames rendered on a running Dask cluster; one of its worker
    processes is killed with SIGKILL after the second commit. Its frames run again
    elsewhere, none is lost or committed twice, and the bytes are the reference's."""
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        pids = [nanny.process.pid for nanny in cluster.workers.values()]
        killed: list[int] = []

        def on_frame_done(done: int, total: int) -> None:
            if done == 2 and not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        out = tmp_path / "dataset"
        summary = generate_dataset(
            parse_scenario(scenario_dict()),
            out,
            scheduler=cluster.scheduler_address,
            on_frame_done=on_frame_done,
        )
    assert killed and summary.complete and summary.rendered == FRAME_COUNT
    indices = [r["frame_index"] for r in read_journal(out)]
    assert indices == list(range(FRAME_COUNT))
    assert file_hashes(out) == reference_hashes


def test_contact_sheet_shows_at_most_36_frames_spread_over_the_dataset() -> None:
    from satsight.dataset.contact_sheet import CONTACT_SHEET_MAX_FRAMES, contact_sheet_frames

    assert contact_sheet_frames(5) == [0, 1, 2, 3, 4]
    for count in (37, 400, 10**6):
        shown = contact_sheet_frames(count)
        assert len(shown) == CONTACT_SHEET_MAX_FRAMES
        assert shown[0] == 0 and shown[-1] == count - 1
        gaps = np.diff(shown)
        assert gaps.max() - gaps.min() <= 1  # evenly spread


def test_an_unreachable_scheduler_is_refused_before_anything_is_written(tmp_path: Path):
    pytest.importorskip("dask.distributed")
    out = tmp_path / "dataset"
    with pytest.raises(SatsightError, match="could not reach the Dask scheduler"):
        generate_dataset(parse_scenario(scenario_dict()), out, scheduler="tcp://127.0.0.1:1")
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_resume_refuses_a_mesh_file_edited_since_the_start(tmp_path: Path) -> None:
    from satsight.scene.obj_export import write_obj
    from satsight.scene.procedural import generate_satellite

    mesh = tmp_path / "sat.obj"
    write_obj(generate_satellite("one_wing", 2), mesh)
    data = scenario_dict()
    data["target"] = {"mesh": {"path": str(mesh)}}
    stop = StopFlag()
    out = tmp_path / "dataset"
    summary = generate_dataset(
        parse_scenario(data), out, on_frame_done=lambda d, n: d >= 1 and stop.set(), stop=stop
    )
    assert summary.interrupted
    with open(mesh, "a", encoding="utf-8") as stream:
        stream.write("# edited\n")
    with pytest.raises(SatsightError, match=r"different settings \(target.mesh_file_sha256\)"):
        generate_dataset(parse_scenario(data), out, resume=True)
