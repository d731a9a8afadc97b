"""Every command's ``--help``: printed without error, no doubled percent sign, and the
commands that print tables say how they print when piped."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from satsight.cli import cli

TABLE_COMMANDS = {"materials", "stats", "validate", "plan", "camera", "ablate"}


@pytest.mark.parametrize("command", sorted(cli.commands))
def test_help_has_no_doubled_percent_sign(command: str) -> None:
    result = CliRunner().invoke(cli, [command, "--help"], terminal_width=200)
    assert result.exit_code == 0, result.output
    assert result.output.startswith(f"Usage: cli {command}")
    assert "%%" not in result.output


def test_lightcurve_help_reads_a_single_percent_sign() -> None:
    result = CliRunner().invoke(cli, ["lightcurve", "--help"], terminal_width=200)
    assert "the target fills 80 % of it" in result.output


@pytest.mark.parametrize("command", sorted(TABLE_COMMANDS))
def test_table_commands_say_how_piped_tables_print(command: str) -> None:
    result = CliRunner().invoke(cli, [command, "--help"], terminal_width=200)
    assert "piped or redirected, it is printed in full as tab-separated text" in result.output
