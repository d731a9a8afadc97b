"""Stand-ins for ``satsight.run.frame_tasks.make_frame`` that run in the render processes of
``tests/run/test_processes.py`` (a module of their own, so that a spawned process imports
them by name)."""

from __future__ import annotations

import os
import signal
import time

from satsight.errors import SatsightError

FAILING_FRAME = 3


def reporting_frame(scenario_json: dict, root: str, index: int, variant: str):
    """A frame's record telling how its process was set up."""
    record = {
        "frame_index": index,
        "scenario": scenario_json,
        "pid": os.getpid(),
        "sigint_ignored": signal.getsignal(signal.SIGINT) is signal.SIG_IGN,
        "render_threads": os.environ.get("SATSIGHT_RENDER_THREADS"),
        "root": root,
        "variant": variant,
    }
    return record, {"render": 0.001, "sensor": 0.002, "files": 0.003}


def failing_frame(scenario_json: dict, root: str, index: int, variant: str):
    """Frame ``FAILING_FRAME`` fails at once with a SatsightError; the others are made in
    0.3 s each (so the failure comes back first)."""
    if index == FAILING_FRAME:
        raise SatsightError(f"frame {index} cannot be made")
    time.sleep(0.3)
    return reporting_frame(scenario_json, root, index, variant)


def dying_frame(scenario_json: dict, root: str, index: int, variant: str):
    """Frame ``FAILING_FRAME`` ends its process at once (as a kill would)."""
    if index == FAILING_FRAME:
        os._exit(3)
    return reporting_frame(scenario_json, root, index, variant)


def failing_start(scenario_json: dict) -> None:
    """A render process's set-up that fails (as a process that cannot start)."""
    raise RuntimeError("this process cannot start")
