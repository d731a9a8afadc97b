"""What every command shares: the console on standard error, the progress bar, the
bundled example, and the exception of a run the user stopped."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

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
