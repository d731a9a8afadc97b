"""What ``satsight validate`` found, and how it is shown: the report, the line for the
problems not kept in full, and the table of checks."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from satsight.dataset.problems import CHECKS, Findings


@dataclass(frozen=True)
class ValidationReport:
    """What ``validate_dataset`` found.

    root: the dataset folder. complete: complete.json present. frame_count: the manifest's
    frame count. frames_checked: frame records whose files and labels were checked.
    findings: the problems (the first ``MAX_KEPT_PROBLEMS`` in full, all counted), and how
    many items each check looked at.
    """

    root: Path
    complete: bool
    frame_count: int
    frames_checked: int
    findings: Findings

    @property
    def ok(self) -> bool:
        """No problem found."""
        return self.findings.total == 0


def omitted_line(report: ValidationReport) -> str | None:
    """A line saying how many problems were found beyond those kept; None when none were."""
    omitted = report.findings.omitted
    if not omitted:
        return None
    return (
        f"... and {omitted} more problem(s), not listed: the first {report.findings.limit} "
        "are kept in full, the table below counts them all"
    )


def summary_table(report: ValidationReport):
    """A rich table: each check, what it looked at and the problems it found."""
    from rich.table import Table

    state = "complete" if report.complete else "incomplete"
    table = Table(
        title=f"{report.root}: {state}, {report.frames_checked} of {report.frame_count} "
        f"frames checked, {report.findings.total} problem(s)"
    )
    for column, justify in (
        ("check", "left"),
        ("what", "left"),
        ("items", "right"),
        ("problems", "right"),
    ):
        table.add_column(column, justify=justify)
    for name, (checked, found) in report.findings.counts().items():
        style = "red" if found else ("green" if checked else "dim")
        table.add_row(name, CHECKS[name], str(checked), str(found), style=style)
    return table
