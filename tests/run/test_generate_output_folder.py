"""``satsight generate`` and ``demo`` refuse an output folder they cannot use at once: a
one-line error and exit status 2, before the scenario's mesh, renderer, stars or plan load
and before any progress is shown."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from satsight.cli import example_scenario_path, main
from satsight.config.scenario import load_scenario
from satsight.dataset.reader import COMPLETE_NAME, DATASET_FORMAT, MANIFEST_NAME


class HeavyStageReached(AssertionError):
    pass


@pytest.fixture(autouse=True)
def no_heavy_stage(monkeypatch) -> None:
    """Make the frame engine (mesh, renderer, star catalogue, plan) fail if it is built."""
    import satsight.pipeline
    import satsight.run.generation

    def refuse(*args, **kwargs):
        raise HeavyStageReached("the frame engine was built before the folder was checked")

    monkeypatch.setattr(satsight.pipeline, "FrameEngine", refuse)
    monkeypatch.setattr(satsight.run.generation, "FrameEngine", refuse)


def fake_dataset(folder: Path, complete: bool) -> Path:
    folder.mkdir()
    (folder / MANIFEST_NAME).write_text(json.dumps({"format": DATASET_FORMAT}), "utf-8")
    if complete:
        (folder / COMPLETE_NAME).write_text("{}", "utf-8")
    return folder


def occupied(folder: Path) -> Path:
    folder.mkdir()
    (folder / "thesis.tex").write_text("precious", encoding="utf-8")
    return folder


def a_file(path: Path) -> Path:
    path.write_text("not a folder", encoding="utf-8")
    return path


CASES = {
    "not empty": (lambda tmp: occupied(tmp / "d"), [], "is not empty and holds no satsight"),
    "overwrite a non-dataset": (
        lambda tmp: occupied(tmp / "d"),
        ["--overwrite"],
        "--overwrite replaces only satsight datasets",
    ),
    "a file": (lambda tmp: a_file(tmp / "d"), [], "exists and is not a folder"),
    "under a file": (lambda tmp: a_file(tmp / "f") / "d", [], "f is a file"),
    "complete dataset": (
        lambda tmp: fake_dataset(tmp / "d", complete=True),
        [],
        "holds a complete dataset; pass --overwrite",
    ),
    "incomplete dataset": (
        lambda tmp: fake_dataset(tmp / "d", complete=False),
        [],
        "holds an incomplete dataset (0 frames committed); pass --resume",
    ),
    "the current folder": (lambda tmp: tmp, [], "is the current folder"),
}


@pytest.mark.parametrize("command", ["generate", "demo"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_output_folder_fails_at_once_without_progress(
    command: str, case: str, tmp_path: Path, monkeypatch, capsys
) -> None:
    make, flags, message = CASES[case]
    out = make(tmp_path)
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    monkeypatch.chdir(tmp_path)
    scenario = [str(example_scenario_path())] if command == "generate" else []
    with pytest.raises(SystemExit) as exit_info:
        main([command, *scenario, "--out", str(out), *flags])
    assert exit_info.value.code == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    # The error alone: no "satsight: scenario ..." line, no progress bar.
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert message in lines[0]
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


def test_generate_dataset_checks_the_folder_before_building_the_engine(tmp_path: Path) -> None:
    from satsight.errors import SatsightError
    from satsight.run.generation import generate_dataset

    scenario = load_scenario(example_scenario_path())
    with pytest.raises(SatsightError, match="is not empty"):
        generate_dataset(scenario, occupied(tmp_path / "d"))


def test_a_usable_folder_goes_on_to_the_heavy_stage(tmp_path: Path, monkeypatch) -> None:
    """The guard above is the frame engine, so a passing check must reach it."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(HeavyStageReached):
        main(["demo", "--out", str(tmp_path / "new")])
