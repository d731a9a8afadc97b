"""A dataset run: the output folder, resuming, shards, and the frame engines that fill it.

Frames are committed one at a time (docs/dataset_format.md): files renamed into place,
then one journal line. An interrupted run keeps every committed frame, and
``generate_dataset(..., resume=True)`` finishes it with the same bytes an uninterrupted run
writes, because every frame depends only on the scenario and its plan index.
"""

from __future__ import annotations

import errno
import logging
import os
import shutil
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from satsight.config.scenario import Scenario
from satsight.config.yaml_safety import load_yaml_file
from satsight.dataset.contact_sheet import (
    contact_sheet_frames,
    keep_thumbnail,
    thumbnail_source,
)
from satsight.dataset.frame_files import FrameArrays, write_frame_files
from satsight.dataset.journal import (
    JOURNAL_NAME,
    JournalFrames,
    JournalWriter,
    file_checksum,
    journal_frames,
    write_bytes_atomic,
)
from satsight.dataset.lock import WriterLock, folder_entries
from satsight.dataset.manifest import (
    finalize_dataset,
    manifest_document,
    scenario_sha256,
    write_manifest,
)
from satsight.dataset.preview import PreviewStretch
from satsight.dataset.reader import COMPLETE_NAME, MANIFEST_NAME, read_json
from satsight.dataset.staging import check_dataset_folder
from satsight.errors import SatsightError
from satsight.pipeline import FrameEngine, RenderedFrame
from satsight.scene.obj_export import write_obj

log = logging.getLogger(__name__)

ProgressCallback = Callable[[int, int], None]
# Threads that encode one frame's files (PNG and EXR encoders release the GIL).
ENCODER_THREADS = 3
# Frames rendered but not yet committed: one being written, one in the sensor, one
# rendering (about 0.5 GB each at 4096 x 4112).
MAX_FRAMES_IN_FLIGHT = 3


@dataclass(frozen=True)
class Shard:
    """Shard ``index`` (0-based) of ``count``: the frames with frame_index % count == index."""

    index: int
    count: int

    @classmethod
    def parse(cls, text: str) -> Shard:
        """A shard from ``K/N`` (K counted from 1, as a user says "shard 1 of 4")."""
        try:
            k, n = (int(part) for part in text.split("/"))
        except ValueError:
            raise SatsightError(f"--shard {text!r}: expected K/N, e.g. 1/4") from None
        if not 1 <= k <= n:
            raise SatsightError(f"--shard {text!r}: K must be between 1 and N")
        return cls(k - 1, n)

    def frames(self, frame_count: int) -> list[int]:
        return list(range(self.index, frame_count, self.count))

    def label(self) -> str:
        return f"{self.index + 1}/{self.count}"


@dataclass
class RunSummary:
    """What a run did. Stage times are per frame rendered in this run (s)."""

    out_dir: Path
    frame_count: int
    committed_before: int
    rendered: int
    complete: bool
    interrupted: bool
    variant: str
    total_seconds: float
    stage_seconds: dict[str, list[float]] = field(default_factory=dict)

    @property
    def render_seconds(self) -> list[float]:
        return self.stage_seconds.get("render", [])


class StopFlag:
    """Set when the user asks the run to stop (Ctrl-C): finish the frames in flight."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def set(self) -> None:
        self._event.set()

    def is_set(self) -> bool:
        return self._event.is_set()


@contextmanager
def stop_on_sigint(flag: StopFlag) -> Iterator[None]:
    """First Ctrl-C sets ``flag`` (the run stops after the frames in flight); a second
    one interrupts at once (committed frames are kept either way)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame) -> None:
        if flag.is_set():
            raise KeyboardInterrupt
        flag.set()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _scenario_json(scenario: Scenario) -> dict:
    return scenario.model_dump(mode="json")


def dataset_manifest(engine: FrameEngine, shard: Shard | None) -> dict:
    """The manifest of the dataset a scenario makes (for one shard of it, or whole)."""
    header = engine.header()
    return manifest_document(
        {
            **header,
            "scenario_sha256": scenario_sha256(_scenario_json(engine.scenario)),
            "shard": None if shard is None else shard.label(),
        }
    )


def _differences(stored: dict, current: dict, prefix: str = "") -> list[str]:
    """Dotted keys whose values differ between two JSON documents."""
    keys = []
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key), current.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            keys += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            keys.append(f"{prefix}{key}")
    return keys


def _check_same_dataset(root: Path, manifest: dict, scenario: Scenario) -> None:
    """Refuse to resume a folder that holds another scenario's (or version's) dataset."""
    stored = read_json(root / MANIFEST_NAME)
    if stored == manifest:
        return
    if stored.get("scenario_sha256") != manifest["scenario_sha256"]:
        try:
            old = load_yaml_file(root / "scenario.yaml")  # the folder may not be ours
            keys = _differences(old if isinstance(old, dict) else {}, _scenario_json(scenario))
        except SatsightError:
            keys = []
        where = f" (differs in {', '.join(keys[:6])})" if keys else ""
        raise SatsightError(
            f"{root} holds a dataset of another scenario{where}; resume with the scenario "
            "and options it was started with, or choose another folder"
        )
    keys = _differences(stored, manifest)
    raise SatsightError(
        f"{root} was started with different settings ({', '.join(keys[:6])}); resume with "
        "what it was started with (the same mesh file, satsight version, shard and render "
        "variant), or choose another folder"
    )


_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO,
                 errno.EFBIG}  # fmt: skip


@contextmanager
def _write_errors_teach(out_dir: Path) -> Iterator[None]:
    """A file system error while the dataset is written becomes one line that names the
    file and says what to do (every committed frame is kept)."""
    try:
        yield
    except SatsightError:
        raise
    except OSError as error:
        path = error.filename or out_dir
        what = "could not write" if error.errno in _WRITE_ERRNOS else "could not use"
        raise SatsightError(
            f"{what} {path}: {error.strerror or error}; the frames committed so far are "
            "kept: free space or fix the folder, then run again with --resume"
        ) from None


def _remove_temporary_files(root: Path) -> None:
    """Delete files a killed run left under temporary names (``.NAME.tmp-PID``)."""
    for folder, _, names in os.walk(root):
        for name in names:
            if name.startswith(".") and ".tmp-" in name:
                Path(folder, name).unlink(missing_ok=True)


# Threads that hash committed files on resume (hashlib releases the GIL), and how many
# frames they may hold at once.
HASH_THREADS = 4
_HASH_WINDOW = 4 * HASH_THREADS


def _damage(root: Path, record: dict) -> str | None:
    """What is wrong with a committed frame's files ("images/frame_000004.png missing",
    "... changed"), or None when each is there with its committed size and SHA-256."""
    for relative, checksum in record.get("checksums", {}).items():
        try:
            if (root / relative).stat().st_size != checksum["size_bytes"]:
                return f"{relative} changed"
            if file_checksum(root / relative)["sha256"] != checksum["sha256"]:
                return f"{relative} changed"
        except OSError:
            return f"{relative} missing"
    return None


def _bounded_map(function: Callable, items, threads: int, window: int) -> Iterator:
    """``map(function, items)`` on ``threads`` threads, in order, with at most ``window``
    items in flight (a 10^6-frame journal is never held whole)."""
    with ThreadPoolExecutor(threads, thread_name_prefix="satsight-hash") as pool:
        pending: deque = deque()
        for item in items:
            pending.append(pool.submit(function, item))
            if len(pending) >= window:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


class CommitTable:
    """Where each committed frame of a run (one shard's frames, or all) lies in the
    journal: two integers per frame, so that a 10^6-frame run keeps no records in memory."""

    def __init__(self, shard: Shard, frame_count: int):
        self.shard = shard
        self.frames = shard.frames(frame_count)
        self._offsets = np.full(len(self.frames), -1, dtype=np.int64)
        self._lengths = np.zeros(len(self.frames), dtype=np.int64)
        self.count = 0

    def _position(self, frame_index: int) -> int | None:
        position, remainder = divmod(frame_index - self.shard.index, self.shard.count)
        if remainder or not 0 <= position < len(self.frames):
            return None
        return position

    def __contains__(self, frame_index: int) -> bool:
        return self._position(frame_index) is not None

    def commit(self, frame_index: int, offset: int, length: int) -> None:
        position = self._position(frame_index)
        if self._offsets[position] < 0:
            self.count += 1
        self._offsets[position] = offset
        self._lengths[position] = length

    def todo(self) -> list[int]:
        """The frames not committed yet, in order."""
        return [self.frames[i] for i in np.flatnonzero(self._offsets < 0)]

    def journal_lines(self, root: Path) -> Iterator[bytes]:
        """Every frame's committed journal line, in frame order."""
        return JournalFrames(root / JOURNAL_NAME, self._offsets, self._lengths).raw_lines()


def committed_frames(root: Path, table: CommitTable) -> list[str]:
    """Enter in ``table`` the frames committed in ``root``'s journal whose files are all
    there with their committed size and SHA-256 (the last line of a frame wins); what is
    wrong with each frame left out (to be rendered again)."""

    def keep(record: dict) -> bool:
        index = int(record["frame_index"])
        if index not in table:
            raise SatsightError(
                f"{root / JOURNAL_NAME} holds frame {index}, which this run does not make "
                "(another shard's or scenario's); use the folder it was started for"
            )
        return True

    lines = journal_frames(root, keep)
    damaged = []
    records = iter(lines) if len(lines) else iter(())
    checks = _bounded_map(lambda record: _damage(root, record), records, HASH_THREADS,
                          _HASH_WINDOW)  # fmt: skip
    spans = zip(lines.indices, lines.offsets, lines.lengths, checks, strict=True)
    for index, offset, length, damage in spans:
        if damage is None:
            table.commit(int(index), int(offset), int(length))
        else:
            damaged.append(f"frame {index}: {damage}")
    return damaged


def prepare_folder(
    out_dir: Path, manifest: dict, scenario: Scenario, overwrite: bool, resume: bool
) -> bool:
    """Make ``out_dir`` ready for the run; True when it already holds a complete dataset.

    A new or empty folder is started; an existing dataset is resumed (``resume``, same
    manifest) or replaced (``overwrite``); anything else is refused before any writing.
    """
    out_dir = Path(out_dir)
    check_dataset_folder(out_dir, overwrite, resume)  # again: the folder may have changed
    if entries := folder_entries(out_dir):  # a dataset (checked above)
        if overwrite:  # all but this run's lock file
            for entry in entries:
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
        else:  # resume
            _check_same_dataset(out_dir, manifest, scenario)
            return (out_dir / COMPLETE_NAME).is_file()
    out_dir.mkdir(parents=True, exist_ok=True)
    write_manifest(out_dir, manifest)
    return False


def _write_dataset_files(root: Path, engine: FrameEngine) -> None:
    """scenario.yaml and the model: rewritten on every start (same bytes each time)."""
    write_bytes_atomic(
        root / "scenario.yaml",
        yaml.safe_dump(_scenario_json(engine.scenario), sort_keys=False).encode("utf-8"),
    )
    (root / "model").mkdir(exist_ok=True)
    write_obj(engine.mesh, root / "model" / "target.obj")


@dataclass
class SensedFrame:
    """A frame after labels, optics and detector: its record (without files) and arrays."""

    record: dict
    arrays: FrameArrays
    crop_box: tuple | None
    sensor_s: float


def sense_frame(engine: FrameEngine, frame: RenderedFrame) -> SensedFrame:
    """Labels, optics and detector of a rendered frame."""
    t0 = time.perf_counter()
    record, arrays, box = engine.finish(frame)
    return SensedFrame(record, arrays, box, time.perf_counter() - t0)


def write_frame(
    engine: FrameEngine, root: Path, sensed: SensedFrame, encoders: ThreadPoolExecutor | None
) -> tuple[dict, dict[str, float]]:
    """Write a sensed frame's files; its journal record and stage times (s)."""
    t0 = time.perf_counter()
    outputs = engine.scenario.outputs
    preview = PreviewStretch.of_outputs(outputs)
    record = sensed.record
    files, crop_files, checksums = write_frame_files(
        root,
        record["frame_index"],
        sensed.arrays,
        outputs.file_keys(),
        sensed.crop_box,
        outputs.crop is None or outputs.crop.full_frame,
        encoders,
        preview,
    )
    record["files"] = files
    if "crop" in record:
        record["crop"]["files"] = crop_files
    record["checksums"] = checksums
    if outputs.contact_sheet and record["frame_index"] in contact_sheet_frames(engine.frame_count):
        source = thumbnail_source(record)
        if source is not None:
            arrays = sensed.arrays.window(sensed.crop_box) if source[1] else sensed.arrays
            dn = arrays.dn_image
            keep_thumbnail(root, record, dn.dn, dn.bias_dn, dn.full_well_dn, preview)
    return record, {"sensor": sensed.sensor_s, "files": time.perf_counter() - t0}


def _run_local(
    engine: FrameEngine,
    root: Path,
    todo: list[int],
    commit: Callable[[dict], None],
    stop: StopFlag,
    times: dict[str, list[float]],
) -> None:
    """Render the frames of ``todo`` in this process as a three-stage pipeline: frame k+2
    renders while frame k+1 goes through the sensor and frame k's files are encoded (on
    ``ENCODER_THREADS`` threads), so that every core stays busy."""
    with (
        ThreadPoolExecutor(max_workers=1, thread_name_prefix="satsight-sensor") as sensor,
        ThreadPoolExecutor(max_workers=1, thread_name_prefix="satsight-writer") as writer,
        ThreadPoolExecutor(ENCODER_THREADS, thread_name_prefix="satsight-encode") as encoders,
    ):
        pending: deque = deque()

        def commit_oldest() -> None:
            record, stage = pending.popleft().result()
            for name, seconds in stage.items():
                times.setdefault(name, []).append(seconds)
            commit(record)

        def sense_then_write(sensed_future) -> tuple[dict, dict[str, float]]:
            return write_frame(engine, root, sensed_future.result(), encoders)

        try:
            for frame_index in todo:
                if stop.is_set():
                    break
                t0 = time.perf_counter()
                frame = engine.render(frame_index)
                times.setdefault("render", []).append(time.perf_counter() - t0)
                sensed = sensor.submit(sense_frame, engine, frame)
                pending.append(writer.submit(sense_then_write, sensed))
                del frame, sensed
                while len(pending) >= MAX_FRAMES_IN_FLIGHT:
                    commit_oldest()
            while pending:
                commit_oldest()
        except BaseException:
            # Frames already in flight are committed if they finish; the error goes on.
            for future in pending:
                future.cancel()
            raise


def generate_dataset(
    scenario: Scenario,
    out_dir: Path,
    overwrite: bool = False,
    resume: bool = False,
    shard: Shard | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    on_frame_done: ProgressCallback | None = None,
    stop: StopFlag | None = None,
) -> RunSummary:
    """Render ``scenario`` into the dataset folder ``out_dir``, frame by frame.

    overwrite: replace a dataset already there. resume: finish the (same) dataset already
    there. shard: render only that shard's frames (joined later by ``satsight merge``).
    workers / scheduler: render on a Dask LocalCluster of that many processes, or on the
    Dask scheduler at that address. on_frame_done(done, total) is called after each
    committed frame. stop: a flag that, once set, ends the run after the frames in flight.
    """
    started = time.perf_counter()
    out_dir = Path(out_dir)
    stop = stop or StopFlag()
    check_dataset_folder(out_dir, overwrite, resume)  # before the mesh, renderer and stars
    engine = FrameEngine(scenario)
    engine.load_star_catalogue()  # fails here, before anything is written
    manifest = dataset_manifest(engine, shard)
    frames = (shard or Shard(0, 1)).frames(engine.frame_count)
    summary = RunSummary(out_dir, len(frames), 0, 0, False, False, manifest["render_variant"], 0.0)
    with ExitStack() as stack:
        stack.enter_context(WriterLock(out_dir))  # one writer per folder, until the end
        stack.enter_context(_write_errors_teach(out_dir))
        client = None
        if workers is not None or scheduler is not None:
            from satsight.distributed import dask_client

            frame_px = (engine.camera.width_px, engine.camera.height_px)
            client = stack.enter_context(dask_client(workers, scheduler, out_dir, frame_px))
        complete = prepare_folder(out_dir, manifest, scenario, overwrite, resume)
        _render_missing_frames(engine, out_dir, manifest, shard or Shard(0, 1), client, summary,
                               stop, on_frame_done, complete)  # fmt: skip
    summary.total_seconds = time.perf_counter() - started
    return summary


def _render_missing_frames(
    engine: FrameEngine,
    out_dir: Path,
    manifest: dict,
    shard: Shard,
    client,
    summary: RunSummary,
    stop: StopFlag,
    on_frame_done: ProgressCallback | None,
    complete: bool = False,
) -> None:
    """Commit every frame of ``shard`` not yet committed in ``out_dir`` (or whose files are
    missing or changed), then close the dataset (unless the run was stopped). complete:
    ``out_dir`` is closed already; it is left untouched when every file is intact."""
    frames = shard.frames(engine.frame_count)
    table = CommitTable(shard, engine.frame_count)
    damaged = committed_frames(out_dir, table)
    summary.committed_before = table.count
    todo = table.todo()
    if complete and not todo:
        summary.complete = True
        return
    if damaged:
        shown = "; ".join(damaged[:5]) + (f"; {len(damaged) - 5} more" if len(damaged) > 5 else "")
        log.warning("%s: rendering again %d committed frames whose files are missing or "
                    "changed (%s)", out_dir, len(damaged), shown)  # fmt: skip
    (out_dir / COMPLETE_NAME).unlink(missing_ok=True)  # repaired below, closed again
    _remove_temporary_files(out_dir)
    _write_dataset_files(out_dir, engine)
    if on_frame_done is not None:
        on_frame_done(table.count, len(frames))

    with JournalWriter(out_dir) as journal:

        def commit(record: dict) -> None:
            offset, length = journal.append(record)
            table.commit(record["frame_index"], offset, length)
            summary.rendered += 1
            if on_frame_done is not None:
                on_frame_done(table.count, len(frames))

        if client is None:
            _run_local(engine, out_dir, todo, commit, stop, summary.stage_seconds)
        else:
            from satsight.distributed import run_distributed

            run_distributed(
                client,
                _scenario_json(engine.scenario),
                out_dir,
                todo,
                commit,
                stop,
                manifest["render_variant"],
            )
    summary.interrupted = table.count < len(frames)
    if not summary.interrupted:
        _remove_temporary_files(out_dir)  # left by workers killed mid-write
        finalize_dataset(out_dir, manifest, table.journal_lines(out_dir))
        summary.complete = True
