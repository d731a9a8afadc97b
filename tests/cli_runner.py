"""Run the ``satsight`` command in a child process, as a user would."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path


def run_satsight(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``python -m satsight ARGS`` in ``cwd``; output captured as text, never raises."""
    env = {**os.environ, "COLUMNS": "200"}  # keep rich from wrapping messages
    return subprocess.run(
        [sys.executable, "-m", "satsight", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        check=False,
    )
