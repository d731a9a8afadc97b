"""How the commands print to standard output: rich tables drawn on a terminal, tab-separated
text when the output is piped or redirected, so that no value is ever cut to fit a width."""

from __future__ import annotations

import inspect
from collections.abc import Iterable

import click
from rich.console import Console
from rich.table import Table
from rich.text import Text

# Appended to the help of every command that prints a table.
PIPED_TABLES_HELP = (
    "On a terminal the table is drawn to fit its width; piped or redirected, it is printed "
    "in full as tab-separated text: a '# title' line, a header line, then one line per row."
)


def stdout_console() -> Console:
    """A console on standard output whose lines are never wrapped or cut."""
    return Console(soft_wrap=True, highlight=False)


def prints_tables(command: click.Command) -> click.Command:
    """Decorator over ``@click.command()``: say in the command's help how its tables print."""
    command.help = f"{inspect.cleandoc(command.help or '')}\n\n{PIPED_TABLES_HELP}".lstrip()
    return command


def _plain(cell: object) -> str:
    """A cell's text without markup or styles, on one line with no tab in it."""
    if isinstance(cell, Text):
        text = cell.plain
    elif isinstance(cell, str):
        text = Text.from_markup(cell).plain
    else:
        text = str(cell)
    return " ".join(text.split("\t")).replace("\r", " ").replace("\n", " ")


def table_as_tsv(table: Table) -> str:
    """``table`` as tab-separated lines: '# title' (if any), the header, the rows."""
    lines = [] if table.title is None else [f"# {_plain(table.title)}"]
    lines.append("\t".join(_plain(column.header) for column in table.columns))
    columns = [[_plain(cell) for cell in column.cells] for column in table.columns]
    lines += ["\t".join(row) for row in zip(*columns, strict=True)]
    return "\n".join(lines)


def print_tables(tables: Iterable[Table]) -> None:
    """Print ``tables`` on standard output: drawn on a terminal, tab-separated (one blank
    line between tables) otherwise."""
    out = Console()
    if out.is_terminal:
        for table in tables:
            out.print(table)
        return
    click.echo("\n\n".join(table_as_tsv(table) for table in tables))
