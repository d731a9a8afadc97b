"""One frame made whole in a process that renders for a run it does not commit: a Dask
worker (``satsight.run.distributed``) or a local render process
(``satsight.run.processes``).

The process builds the scenario's ``FrameEngine`` on its first frame and keeps it (mesh,
plan, sensor, the renderer and its compiled kernels) with its file encoders; each task
renders a frame, senses it and writes its files into the dataset folder, and hands back
the frame's record for the run's one journal.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from satsight.config.scenario import parse_scenario
from satsight.dataset.manifest import scenario_sha256
from satsight.errors import SatsightError

_ENGINES: dict = {}
_ENCODERS: list[ThreadPoolExecutor] = []
_KEYED: list = []  # [the last scenario object asked for, its hash] (kept, so never reused)


def process_engine(scenario_json: dict):
    """This process's FrameEngine for a scenario, built on its first frame and kept."""
    from satsight.pipeline import FrameEngine

    if _KEYED and _KEYED[0] is scenario_json:  # the same object as before: no hash again
        key = _KEYED[1]
    else:
        key = scenario_sha256(scenario_json)
        _KEYED[:] = [scenario_json, key]
    if key not in _ENGINES:
        _ENGINES.clear()  # one scenario at a time per process
        _ENGINES[key] = FrameEngine(parse_scenario(scenario_json, "scenario"))
    if not _ENCODERS:
        from threadpoolctl import threadpool_limits

        from satsight.run.frame_stages import ENCODER_THREADS
        from satsight.run.local import BLAS_THREADS

        threadpool_limits(limits=BLAS_THREADS, user_api="blas")  # for the process's life
        _ENCODERS.append(ThreadPoolExecutor(ENCODER_THREADS))
    return _ENGINES[key]


def make_frame(
    scenario_json: dict, root: str, frame_index: int, variant: str
) -> tuple[dict, dict[str, float]]:
    """Render, sense and write frame ``frame_index`` into the dataset folder ``root``; its
    journal record and its stage times (s: render, sensor, files)."""
    from satsight.run.frame_stages import sense_frame, write_frame

    engine = process_engine(scenario_json)
    if engine.renderer.variant != variant:
        raise SatsightError(
            f"a worker or render process renders with {engine.renderer.variant}, the dataset "
            f"with {variant}; "
            "set render.variant in the scenario so that every worker uses the same one"
        )
    t0 = time.perf_counter()
    frame = engine.render(frame_index)
    render_s = time.perf_counter() - t0
    record, times = write_frame(engine, Path(root), sense_frame(engine, frame), _ENCODERS[0])
    return record, {"render": render_s, **times}
