"""Command line: ``satsight demo | generate | merge | validate | stats | export | plan |
camera | ablate | bench | satellite | materials | fit-brdf |
lightcurve``.

A thin shell over ``satsight.run``, ``satsight.dataset`` and the other stages, its
commands in ``satsight.commands``: user errors print a message and exit with status 2,
never a traceback; a run stopped by Ctrl-C exits with 130 after saying how to resume it.
"""

from __future__ import annotations

import sys

import click

from satsight.commands import datasets, describe, materials, measure
from satsight.commands.shell import Interrupted, console, example_scenario_path
from satsight.errors import SatsightError

__all__ = ["cli", "example_scenario_path", "main"]


@click.group()
@click.version_option(package_name="satsight")
def cli() -> None:
    """satsight: physically based optical images of space objects with exact labels."""


for _command in (
    datasets.demo,
    datasets.generate,
    datasets.merge,
    datasets.validate,
    datasets.stats,
    datasets.export,
    describe.plan,
    describe.camera,
    describe.satellite,
    describe.lightcurve,
    measure.ablate,
    measure.bench,
    materials.materials,
    materials.fit_brdf,
):
    cli.add_command(_command)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``satsight`` command."""
    try:
        cli.main(args=argv, standalone_mode=False)
    except click.exceptions.Abort:
        console.print("aborted")
        sys.exit(130)
    except Interrupted as error:
        console.print(str(error), highlight=False)
        sys.exit(130)
    except KeyboardInterrupt:
        console.print(
            "interrupted; the frames committed so far are kept: run the same command with "
            "--resume to finish"
        )
        sys.exit(130)
    except click.ClickException as error:
        error.show()
        sys.exit(error.exit_code)
    except SatsightError as error:
        console.print(f"[red]error:[/red] {error}", highlight=False)
        sys.exit(2)
    except OSError as error:
        where = f": {error.filename}" if error.filename else ""
        console.print(f"[red]error:[/red] {error.strerror or error}{where}", highlight=False)
        sys.exit(2)
