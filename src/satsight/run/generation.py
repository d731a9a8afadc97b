"""A dataset run: the output folder, resuming, shards, and the frame engines that fill it.

Frames are committed one at a time (docs/dataset_format.md): files renamed into place,
then one journal line. An interrupted run keeps every committed frame, and
``generate_dataset(..., resume=True)`` finishes it with the same bytes an uninterrupted run
writes, because every frame depends only on the scenario and its plan index.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

from satsight.config.scenario import Scenario
from satsight.dataset.journal import JournalWriter
from satsight.dataset.lock import WriterLock
from satsight.dataset.manifest import finalize_dataset
from satsight.dataset.reader import COMPLETE_NAME
from satsight.dataset.staging import check_dataset_folder
from satsight.errors import SatsightError
from satsight.frame_memory import PIPELINED_FRAMES, frames_in_flight
from satsight.pipeline import FrameEngine
from satsight.run.commit_table import CommitTable, committed_frames
from satsight.run.dataset_folder import (
    dataset_manifest,
    prepare_folder,
    remove_temporary_files,
    scenario_json,
    write_dataset_files,
    write_errors_teach,
)
from satsight.run.interrupt import StopFlag
from satsight.run.local import run_local
from satsight.run.processes import local_processes, requested_processes, run_processes
from satsight.run.shard import Shard

log = logging.getLogger(__name__)

ProgressCallback = Callable[[int, int], None]


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
    render_processes: int = 1  # local render processes that made the frames (1: this one)

    @property
    def render_seconds(self) -> list[float]:
        return self.stage_seconds.get("render", [])


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
    render_processes: int | str = 1,
) -> RunSummary:
    """Render ``scenario`` into the dataset folder ``out_dir``, frame by frame.

    overwrite: replace a dataset already there. resume: finish the (same) dataset already
    there. shard: render only that shard's frames (joined later by ``satsight merge``).
    workers / scheduler: render on a Dask LocalCluster of that many processes, or on the
    Dask scheduler at that address. on_frame_done(done, total) is called after each
    committed frame, one call at a time, on the thread that commits (in a pipelined local
    run the files' writer, not the caller's). stop: a flag that, once set, ends the run
    after the frames in flight. render_processes: without workers or a scheduler, render
    in that many local processes (``satsight.run.processes``), or ``"auto"``: as
    ``local_processes`` decides for the frame size and count (``satsight generate``'s
    choice). Processes are started by spawning, so a script that asks for more than one
    needs Python's ``if __name__ == "__main__":`` guard.
    """
    started = time.perf_counter()
    out_dir = Path(out_dir)
    stop = stop or StopFlag()
    _check_render_processes(render_processes)
    check_dataset_folder(out_dir, overwrite, resume)  # before the mesh, renderer and stars
    # Frames in flight from the memory available before anything is loaded (the estimate
    # holds the run's fixed cost).
    camera = scenario.camera.build()
    in_flight, why_one = frames_in_flight(camera.width_px, camera.height_px)
    engine = FrameEngine(scenario, keeps_buffers=False)
    engine.load_star_catalogue()  # fails here, before anything is written
    manifest = dataset_manifest(engine, shard)
    frames = (shard or Shard(0, 1)).frames(engine.frame_count)
    summary = RunSummary(out_dir, len(frames), 0, 0, False, False, manifest["render_variant"], 0.0)
    with ExitStack() as stack:
        stack.enter_context(WriterLock(out_dir))  # one writer per folder, until the end
        stack.enter_context(write_errors_teach(out_dir))
        client = None
        if workers is not None and scheduler is None:
            from satsight.run.distributed import local_workers

            workers, why = local_workers(workers)
            if why is not None:
                log.warning("%s", why)
        if workers is not None or scheduler is not None:
            from satsight.run.distributed import dask_client

            frame_px = (engine.camera.width_px, engine.camera.height_px)
            client = stack.enter_context(dask_client(workers, scheduler, out_dir, frame_px))
        complete = prepare_folder(out_dir, manifest, scenario, overwrite, resume)
        _render_missing_frames(engine, out_dir, manifest, shard or Shard(0, 1), client, summary,
                               stop, on_frame_done, complete, in_flight,
                               render_processes, why_one)  # fmt: skip
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
    in_flight: int = PIPELINED_FRAMES,
    render_processes: int | str = 1,
    why_one: str | None = None,
) -> None:
    """Commit every frame of ``shard`` not yet committed in ``out_dir`` (or whose files are
    missing or changed), then close the dataset (unless the run was stopped). complete:
    ``out_dir`` is closed already; it is left untouched when every file is intact.
    in_flight: frames in flight when they are rendered in this process (``run_local``), and
    why_one: why only one is (said when this process makes the frames).
    render_processes: ``generate_dataset``'s."""
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
    remove_temporary_files(out_dir)
    write_dataset_files(out_dir, engine)
    if on_frame_done is not None:
        on_frame_done(table.count, len(frames))

    with JournalWriter(out_dir) as journal:

        def commit(record: dict) -> None:
            offset, length = journal.append(record)
            table.commit(record["frame_index"], offset, length)
            summary.rendered += 1
            if on_frame_done is not None:
                on_frame_done(table.count, len(frames))

        variant = manifest["render_variant"]
        if client is not None:
            from satsight.run.distributed import run_distributed

            run_distributed(
                client, scenario_json(engine.scenario), out_dir, todo, commit, stop, variant
            )
        elif (processes := _processes(engine, variant, render_processes, len(todo))) > 1:
            summary.render_processes = processes
            run_processes(variant, scenario_json(engine.scenario), out_dir, todo, commit, stop,
                          summary.stage_seconds, processes)  # fmt: skip
        else:
            if why_one is not None:  # (said only where this process makes the frames)
                log.warning("%s", why_one)
            run_local(engine, out_dir, todo, commit, stop, summary.stage_seconds, in_flight)
    summary.interrupted = table.count < len(frames)
    if not summary.interrupted:
        remove_temporary_files(out_dir)  # left by workers killed mid-write
        finalize_dataset(out_dir, manifest, table.journal_lines(out_dir))
        summary.complete = True


def _processes(engine: FrameEngine, variant: str, requested: int | str, frames: int) -> int:
    """Local render processes for ``frames`` frames (1 when there are none): ``requested``,
    or ``local_processes``' choice for ``"auto"`` (its reason logged)."""
    if frames == 0:
        return 1
    if requested == "auto":
        camera = engine.camera
        count, why = local_processes(camera.width_px, camera.height_px, frames, variant=variant)
        if why is not None:
            log.info("%s", why)
        return count
    return requested


def _check_render_processes(requested: int | str) -> None:
    """A clear error, before anything is written, for a bad ``render_processes`` (or, with
    ``"auto"``, a bad ``SATSIGHT_LOCAL_PROCESSES``)."""
    if requested == "auto":
        requested_processes()
    elif isinstance(requested, bool) or not isinstance(requested, int) or requested < 1:
        raise SatsightError(
            f"render_processes must be a whole number >= 1 or 'auto', got {requested!r}"
        )
