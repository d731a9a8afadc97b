"""Small frames made by local render processes, one per core, while this process commits.

A small frame's work is mostly Python: tracing the renderer's kernels, the sensor's and
the writer's bookkeeping. Python runs one thread at a time per process, so the threads of
one process (``satsight.run.local``) leave a core idle for much of each frame: 1024 x 1024
lean frames of the RSSF example took 69-79 ms each there with 147-150 % CPU on 2 cores.
One process per core, each making whole frames (``satsight.run.frame_tasks``), made them in
45 ms (the measures are in docs/design.md, "Render processes"). A process costs its
start-up (about 1.5 s: its imports, its own scenario, plan, star catalogue and compiled
kernels) and its own memory, so they start only for enough frames that fit in memory
(``local_processes``).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from satsight.errors import SatsightError
from satsight.frame_memory import frame_memory_bytes, memory_limit_bytes
from satsight.render.backend import CPU_VARIANT, machine_cores
from satsight.run.frame_tasks import make_frame
from satsight.run.interrupt import StopFlag, sigint_ignored

#: Environment variable that sets the number of render processes of a local run that
#: lets satsight choose (``satsight generate``; ``render_processes="auto"`` in Python): a
#: whole number >= 1 (1: this process renders), or ``auto`` (unset: ``local_processes``).
PROCESSES_VARIABLE = "SATSIGHT_LOCAL_PROCESSES"
#: Largest frame (pixels) made by render processes. Measured at 1024 x 1024; at 4096 x 4112
#: the sensor and the encoders release the interpreter's lock for most of their work, and
#: one process keeps the cores busy with about half the memory of two.
PROCESS_MAX_PIXELS = 1 << 21
#: Fewest frames to make for render processes to repay their start-up (1.4 s more than
#: one process at 1024 x 1024, 25 ms saved a frame: even at about 60 frames).
PROCESS_MIN_FRAMES = 100
#: Frames queued per process beyond the one it makes, so that none waits for this one.
_QUEUED_PER_PROCESS = 1


def requested_processes(environ: dict | None = None) -> int | None:
    """The render processes ``SATSIGHT_LOCAL_PROCESSES`` asks for (None: ``auto``, unset)."""
    env = os.environ if environ is None else environ
    text = env.get(PROCESSES_VARIABLE, "").strip().lower()
    if text in ("", "auto"):
        return None
    if not text.isdecimal() or int(text) < 1:
        raise SatsightError(
            f"{PROCESSES_VARIABLE}={text!r}: expected a whole number >= 1 of render "
            "processes (1: this process renders) or 'auto'"
        )
    return int(text)


def local_processes(
    width_px: int,
    height_px: int,
    frames: int,
    cores: int | None = None,
    memory_bytes: float | None = None,
    environ: dict | None = None,
    variant: str = CPU_VARIANT,
) -> tuple[int, str | None]:
    """How many render processes a local run of ``frames`` width x height px frames starts
    (1: none, this process renders), and why, when more than one (None otherwise).

    ``SATSIGHT_LOCAL_PROCESSES`` = N sets N (1 turns them off); by default one per core
    (``cores``, default the machine's), for frames of at most ``PROCESS_MAX_PIXELS`` and at
    least ``PROCESS_MIN_FRAMES`` of them rendered on the CPU (``variant``; on a GPU each
    process would hold its own copy of the scene and buffers there), as many as fit in
    ``memory_bytes`` (default: ``memory_limit_bytes``) at a kept-buffer frame each, less a
    one-process run's estimate for this process (conservative: this process renders no
    frame, and the memory available is read after it has loaded its engine)."""
    count = requested_processes(environ)
    if count is not None:
        why = f"{count} render processes ({PROCESSES_VARIABLE}={count})"
        return count, why if count > 1 else None
    cores = machine_cores() if cores is None else cores
    small = width_px * height_px <= PROCESS_MAX_PIXELS
    if cores < 2 or not small or frames < PROCESS_MIN_FRAMES or variant != CPU_VARIANT:
        return 1, None
    memory_bytes = memory_limit_bytes(environ) if memory_bytes is None else memory_bytes
    count = cores
    if memory_bytes is not None:
        own = frame_memory_bytes(width_px, height_px, kept=False)
        each = frame_memory_bytes(width_px, height_px, kept=True)
        count = min(cores, int((memory_bytes - own) // each))
    if count < 2:
        return 1, None
    return count, (
        f"{count} render processes, one per core: {width_px} x {height_px} px frames are "
        f"made faster side by side than by the threads of one process ({PROCESSES_VARIABLE}=1 "
        "renders in this process)"
    )


def run_processes(
    variant: str,
    scenario_json: dict,
    root: Path,
    todo: list[int],
    commit: Callable[[dict], None],
    stop: StopFlag,
    times: dict[str, list[float]],
    processes: int,
) -> None:
    """Make the frames of ``todo`` in ``processes`` render processes and ``commit`` each
    record as it comes back (the lowest frame first among those done together).

    ``scenario_json``: the scenario as ``satsight.run.dataset_folder.scenario_json`` gives
    it, handed to each process once, when it starts; ``variant``: the dataset's render
    variant, which every process must use. Each process renders on one thread (the
    processes fill the cores) and ignores Ctrl-C: a stop (``stop``) ends the run after the
    frames in flight, which are committed. A frame that fails raises its error here, after
    the frames in flight that succeed are committed, and no frame is started after it; a
    process that dies (killed, out of memory) or cannot start raises a SatsightError."""
    root = Path(os.path.abspath(root))
    queue = iter(todo)
    pending: dict = {}  # future -> frame index
    failures: list[BaseException] = []  # a frame's error, raised once the others are in
    committed = 0
    context = multiprocessing.get_context("spawn")  # no fork of a process with JIT threads
    with ProcessPoolExecutor(
        processes, mp_context=context, initializer=_start_process, initargs=(scenario_json,)
    ) as pool:

        def submit_next() -> None:
            index = next(queue, None)
            if index is not None and not stop.is_set() and not failures:
                # The function goes by name (``make_frame`` unless replaced), the scenario
                # not at all: each process keeps its own (``_start_process``).
                future = pool.submit(_frame_in_process, make_frame, str(root), index, variant)
                pending[future] = index

        try:
            with sigint_ignored():  # the processes start with the first submits
                for _ in range(processes * (1 + _QUEUED_PER_PROCESS)):
                    submit_next()
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                made = []
                for future in sorted(done, key=pending.__getitem__):
                    index = pending.pop(future)
                    error = future.exception()
                    if error is None:
                        made.append(future.result())
                    elif isinstance(error, BrokenProcessPool):
                        failures.append(_broken(error, index, committed + len(made)))
                    else:
                        failures.append(error)
                for record, stage in made:  # a failure seen, they are still committed
                    for name, seconds in stage.items():
                        times.setdefault(name, []).append(seconds)
                    commit(record)
                    committed += 1
                for _ in made:
                    submit_next()  # (none once a frame has failed)
        except BaseException:
            for future in pending:
                future.cancel()
            raise
    if failures:
        raise failures[0]


def _broken(error: BaseException, index: int, made: int) -> SatsightError:
    """The error for a pool whose process died (``error``) with frame ``index`` in flight,
    ``made`` frames having come back before."""
    if made == 0:
        what = (
            "the render processes ended before any frame came back (did they start? A "
            'script that asks for render processes needs Python\'s `if __name__ == "__main__":` '
            "guard)"
        )
    else:
        what = "a render process ended (killed, or out of memory?)"
    return SatsightError(
        f"{what} while frame {index} was in flight ({error}); the frames committed so far "
        "are kept: resume the run (--resume, or resume=True)"
    )


_SCENARIO: list[dict] = []  # in a render process: its scenario (``_start_process``)


def _start_process(scenario_json: dict) -> None:
    """A render process's set-up: its scenario kept for every frame, Ctrl-C ignored (also
    inherited from ``sigint_ignored`` where the process started within it), and its
    renderer on one thread (the processes fill the cores), unless the user set
    ``SATSIGHT_RENDER_THREADS``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("SATSIGHT_RENDER_THREADS", "1")
    _SCENARIO[:] = [scenario_json]


def _frame_in_process(frame: Callable, root: str, index: int, variant: str):
    """In a render process: ``frame`` (``make_frame``) of frame ``index`` with the
    process's scenario."""
    return frame(_SCENARIO[0], root, index, variant)
