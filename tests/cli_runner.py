"""Run the ``satsight`` command as a user would: in a child process, or in this interpreter."""

from __future__ import annotations

import contextlib
import io
import logging
import os
import re
import subprocess
import sys
import traceback
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


# Colour codes: a console started on a terminal (``pytest -s``) colours its text; a pipe
# gets none.
_ANSI_CODE = re.compile(r"\x1b\[[0-9;]*m")


def invoke_satsight(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``satsight ARGS`` in this interpreter, in ``cwd``: the exit status, standard output
    and standard error that ``run_satsight`` gives, without starting Python again.

    For tests of a command's messages, exit status and files. Warnings the library logs
    reach standard error as in the command (Python's last-resort handler: the message
    alone, WARNING and above); an exception that escapes the command is a traceback on
    standard error and status 1, as in a child process. A hostile input that could bring
    the interpreter itself down belongs in ``run_satsight``.
    """
    from satsight.cli import main

    stdout, stderr = io.StringIO(), io.StringIO()
    warnings = logging.StreamHandler(stderr)
    warnings.setLevel(logging.WARNING)
    root = logging.getLogger()
    root.addHandler(warnings)
    returncode = 0
    try:
        with (
            contextlib.chdir(cwd),
            contextlib.redirect_stdout(stdout),
            contextlib.redirect_stderr(stderr),
        ):
            try:
                main(list(args))
            except SystemExit as error:
                returncode = error.code if isinstance(error.code, int) else int(bool(error.code))
            except Exception:  # what the interpreter prints before it exits with status 1
                traceback.print_exc()
                returncode = 1
    finally:
        root.removeHandler(warnings)
    return subprocess.CompletedProcess(
        ["satsight", *args],
        returncode,
        _ANSI_CODE.sub("", stdout.getvalue()),
        _ANSI_CODE.sub("", stderr.getvalue()),
    )
