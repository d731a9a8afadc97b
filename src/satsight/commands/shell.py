"""What every command shares: the console on standard error, the progress bar, the
bundled example, and the exception of a run the user stopped."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import click
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from satsight.errors import SatsightError

console = Console(stderr=True, soft_wrap=True)


def example_scenario_path() -> Path:
    """Path of the bundled example scenario."""
    return Path(str(resources.files("satsight") / "examples" / "first_light.yaml"))


def progress_bar() -> Progress:
    """A progress bar on standard error: description, bar, done/total, elapsed time."""
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
    )


class Interrupted(SatsightError):
    """The user stopped a run; committed frames are kept (exit status 130)."""


def report_folder_option(default: str, holds: str):
    """The ``--out DIR`` option of a command that writes a few report files (``holds``) into
    a folder of their own: created, files of the same name replaced."""
    return click.option(
        "--out",
        "out_dir",
        type=click.Path(path_type=Path),
        default=Path(default),
        show_default=True,
        help=f"folder for {holds} (created; files of the same name are replaced)",
    )
