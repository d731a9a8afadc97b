"""Frames rendered in this process: a three-stage pipeline (render, sensor, files) that
keeps every core busy."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from threadpoolctl import threadpool_limits

from satsight.pipeline import FrameEngine
from satsight.render.backend import render_threads_beside_other_work
from satsight.run.frame_stages import ENCODER_THREADS, sense_frame, write_frame
from satsight.run.interrupt import StopFlag

# BLAS threads while frames are made: numpy's BLAS only multiplies a frame's three colour
# channels by their weights, and its idle threads spin, taking the cores from the other
# stages. Measured on 2 cores, RSSF example, 20 frames with lean outputs (two rounds in one
# run): 4096 x 4112 0.85 / 0.88 -> 0.77 / 0.74 s a frame, 1024 x 1024 steady 0.168 / 0.160
# -> 0.141 / 0.143 s, its CPU use 161 -> 128 %.
BLAS_THREADS = 1

# Frames rendered but not yet committed: one in the sensor or being written while the next
# renders (about 0.5 GB each at 4096 x 4112). Measured on the RSSF example, 20 frames at
# 4096 x 4112, all outputs, 2 cores: 3 in flight 1.18-1.24 s a frame and a 3.3 GB peak,
# 2 in flight 1.10-1.18 s and 2.8 GB, 1 in flight 1.22 s and 2.1 GB.
MAX_FRAMES_IN_FLIGHT = 2


def run_local(
    engine: FrameEngine,
    root: Path,
    todo: list[int],
    commit: Callable[[dict], None],
    stop: StopFlag,
    times: dict[str, list[float]],
) -> None:
    """Render the frames of ``todo`` in this process as a three-stage pipeline: frame k+2
    renders while frame k+1 goes through the sensor and frame k's files are encoded (on
    ``ENCODER_THREADS`` threads), so that every core stays busy; the renderer keeps one core
    fewer than the machine's for its threads (``render_threads_beside_other_work``) and
    numpy's BLAS ``BLAS_THREADS``."""
    with (
        render_threads_beside_other_work(engine.renderer.variant),
        threadpool_limits(limits=BLAS_THREADS, user_api="blas"),
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
