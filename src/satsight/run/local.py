"""Frames rendered in this process: a three-stage pipeline (render, sensor, files) that
keeps every core busy."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from pathlib import Path

from threadpoolctl import threadpool_limits

from satsight.frame_memory import return_freed_heap
from satsight.pipeline import FrameEngine
from satsight.render.backend import release_render_memory, render_threads_beside_other_work
from satsight.run.frame_stages import ENCODER_THREADS, sense_frame, write_frame
from satsight.run.interrupt import StopFlag

# BLAS threads while frames are made: numpy's BLAS only multiplies a frame's three colour
# channels by their weights, and its idle threads spin, taking the cores from the other
# stages. Measured on 2 cores, RSSF example, 20 frames with lean outputs (two rounds in one
# run): 4096 x 4112 0.85 / 0.88 -> 0.77 / 0.74 s a frame, 1024 x 1024 steady 0.168 / 0.160
# -> 0.141 / 0.143 s, its CPU use 161 -> 128 %.
BLAS_THREADS = 1


def run_local(
    engine: FrameEngine,
    root: Path,
    todo: list[int],
    commit: Callable[[dict], None],
    stop: StopFlag,
    times: dict[str, list[float]],
    in_flight: int,
) -> None:
    """Render the frames of ``todo`` in this process as a three-stage pipeline: frame k+1
    renders while frame k goes through the sensor and then has its files encoded (on
    ``ENCODER_THREADS`` threads), so that every core stays busy; the renderer keeps one core
    fewer than the machine's for its threads (``render_threads_beside_other_work``) and
    numpy's BLAS ``BLAS_THREADS``. Frames are committed (``commit``) in their order on the
    writer's thread, right after their files: the render thread, the one that bounds the
    rate of small frames, only renders (a commit's journal line, its fsync and the
    progress bar took 2-3 ms a frame from it at 1024 x 1024).

    in_flight: frames rendered but not yet committed (``generate_dataset`` takes it from
    ``satsight.frame_memory.frames_in_flight``). With 1, each frame is rendered, sensed
    and written on this thread before the next (the renderer then keeps all its threads);
    the renderer's freed buffers go back to the system before its sensor stage, and the
    heap freed by the sensor and the writer before the next render: the least memory, at
    some speed."""
    variant = engine.renderer.variant
    with (
        render_threads_beside_other_work(variant) if in_flight > 1 else nullcontext(),
        threadpool_limits(limits=BLAS_THREADS, user_api="blas"),
        # Shut down in reverse: the writer's frames in flight finish (and commit) while the
        # sensor and the encoders they wait for are still there.
        ThreadPoolExecutor(ENCODER_THREADS, thread_name_prefix="satsight-encode") as encoders,
        ThreadPoolExecutor(max_workers=1, thread_name_prefix="satsight-sensor") as sensor,
        ThreadPoolExecutor(max_workers=1, thread_name_prefix="satsight-writer") as writer,
    ):
        pending: deque = deque()

        def record_and_commit(record: dict, stage: dict[str, float]) -> None:
            for name, seconds in stage.items():
                times.setdefault(name, []).append(seconds)
            commit(record)

        def sense_write_commit(sensed_future) -> None:
            # One writer thread: frames are written and committed in their order.
            record_and_commit(*write_frame(engine, root, sensed_future.result(), encoders))

        try:
            for frame_index in todo:
                if stop.is_set():
                    break
                t0 = time.perf_counter()
                frame = engine.render(frame_index)
                times.setdefault("render", []).append(time.perf_counter() - t0)
                if in_flight == 1:  # each stage in turn, on this thread
                    release_render_memory(variant)  # the render's temporaries
                    sensed = sense_frame(engine, frame)
                    del frame
                    record, stage = write_frame(engine, root, sensed, encoders)
                    del sensed
                    record_and_commit(record, stage)
                    return_freed_heap()  # what the sensor and the files left in the heap
                    continue
                sensed = sensor.submit(sense_frame, engine, frame)
                pending.append(writer.submit(sense_write_commit, sensed))
                del frame, sensed
                while len(pending) >= in_flight:
                    pending.popleft().result()  # committed (or its error raised here)
            while pending:
                pending.popleft().result()
        except BaseException:
            # Frames already in flight are committed if they finish; the error goes on.
            for future in pending:
                future.cancel()
            raise
