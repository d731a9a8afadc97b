"""Hostile scenario files: each is refused with a one-line message, quickly, leaving nothing."""

from __future__ import annotations

import os
import time
import tracemalloc
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import pytest

from cli_runner import invoke_satsight, run_satsight
from satsight.config import yaml_safety
from satsight.config.scenario import load_scenario
from satsight.config.yaml_safety import MAX_ALIASES, MAX_DEPTH, load_yaml_file
from satsight.errors import SatsightError

VALID_TAIL = "target: {procedural: {satellite_class: two_wings}}\nframes: [{distance_km: 1.0}]\n"


def _laughs(indent: str = "") -> str:
    """A 'billion laughs': nine levels of nine aliases each, 9**9 values once expanded."""
    lines = [f"{indent}a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    for level in range(1, 9):
        lines.append(f"{indent}a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * 9)}]")
    return "\n".join(lines) + "\n"


def _write(text: str | bytes) -> Callable[[Path], Path]:
    def make(folder: Path) -> Path:
        path = folder / "scenario.yaml"
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")
        return path

    return make


def _directory(folder: Path) -> Path:
    path = folder / "scenario.yaml"
    path.mkdir()
    return path


def _symlink_loop(folder: Path) -> Path:
    (folder / "a.yaml").symlink_to(folder / "b.yaml")
    (folder / "b.yaml").symlink_to(folder / "a.yaml")
    return folder / "a.yaml"


_FRAME_ALIASES = "".join("  - *f\n" for _ in range(MAX_ALIASES))

# name -> (writes the scenario into a folder and returns its path, part of the message)
HOSTILE: dict[str, tuple[Callable[[Path], Path], str]] = {
    "alias bomb in name": (_write("name:\n" + _laughs("  ") + VALID_TAIL), "aliases expanded"),
    "alias bomb in frames": (
        _write("name: x\ntarget: {procedural: {}}\nbomb:\n" + _laughs("  ") + "frames: *a8\n"),
        "aliases expanded",
    ),
    "too many aliases": (
        _write(
            "name: x\ntarget: {procedural: {}}\nframes:\n  - &f {distance_km: 1}\n"
            + _FRAME_ALIASES
            + "  - *f\n"
        ),
        f"more than {MAX_ALIASES} aliases",
    ),
    "alias inside its own anchor": (
        _write("name: x\nframes: &a [*a]\n"),
        "inside its own anchor",
    ),
    "10 000 nested lists": (_write("name: " + "[" * 10_000 + "]" * 10_000 + "\n"), "nested"),
    "10 000 nested mappings": (_write("name: " + "{a: " * 10_000 + "1" + "}" * 10_000), "nested"),
    "100 nested block mappings": (
        _write("".join(" " * level + f"k{level}:\n" for level in range(100)) + " " * 100 + "1\n"),
        f"nested more than {MAX_DEPTH} levels",
    ),
    "alias nesting past the limit": (
        _write("a: &deep " + "[" * (MAX_DEPTH - 2) + "]" * (MAX_DEPTH - 2) + "\nb: [[[*deep]]]\n"),
        "alias *deep nests more than",
    ),
    "duplicate top-level key": (
        _write("name: x\nseed: 1\n" + VALID_TAIL + "seed: 2\n"),
        "key 'seed' given twice, on lines 2 and 5",
    ),
    "duplicate nested key": (
        _write("name: x\ntarget:\n  procedural:\n    seed: 1\n    seed: 2\nframes: []\n"),
        "key 'seed' given twice, on lines 4 and 5",
    ),
    "empty file": (_write(""), "expected a mapping of keys at the top level"),
    "a list, not a mapping": (_write("- 1\n- 2\n"), "expected a mapping of keys at the top level"),
    "binary, not UTF-8": (_write(bytes(range(256)) * 8), "not a UTF-8 text file"),
    "binary with NUL bytes": (_write(b"name: x\x00\x01\x02\x03" * 10), "not a text file"),
    "larger than the cap": (_write("name: x\n" + "# padding\n" * 110_000), "larger than 1024 KiB"),
    "python/object tag": (_write("name: !!python/object:os.system {}\n"), "is not allowed"),
    "python/object/apply tag": (
        _write("name: !!python/object/apply:os.system ['echo owned']\n"),
        "is not allowed",
    ),
    "impossible date": (_write("name: 2001-13-45\n" + VALID_TAIL), "month must be in 1..12"),
    "5000-digit integer": (_write("name: x\nseed: " + "9" * 5000 + "\n"), "cannot read"),
    "a folder": (_directory, "is a folder"),
    "a symbolic link loop": (_symlink_loop, "symbolic link"),
}

# The case run in a child process, as typed at the command line: the deepest recursion a
# parser could attempt, the one that could end the interpreter rather than raise. The
# others check the message and exit status, the same in this interpreter.
IN_A_CHILD_PROCESS = "10 000 nested lists"


@pytest.mark.parametrize("case", list(HOSTILE))
def test_generate_refuses_hostile_scenario_in_one_line(case: str, tmp_path: Path) -> None:
    make, message = HOSTILE[case]
    inputs = tmp_path / "in"
    inputs.mkdir()
    path = make(inputs)
    out = tmp_path / "out"
    run = run_satsight if case == IN_A_CHILD_PROCESS else invoke_satsight
    result = run("generate", str(path), "--out", str(out), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr[:2000]
    assert lines[0].startswith("error: "), lines[0]
    assert str(path) in lines[0]
    assert message in lines[0]
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]  # no partial folder beside


# --- load_scenario directly ---------------------------------------------------------------
def test_duplicate_key_names_the_key_and_both_lines(tmp_path: Path) -> None:
    path = tmp_path / "twice.yaml"
    path.write_text(
        "name: x\ncamera:\n  preset: wide_field\n  seed: 1\n" + VALID_TAIL + "camera:\n  seed: 2\n",
        encoding="utf-8",
    )
    with pytest.raises(SatsightError, match="key 'camera' given twice") as info:
        load_scenario(path)
    assert str(info.value) == f"{path}: key 'camera' given twice, on lines 2 and 7; keep one"


def test_duplicate_key_in_a_flow_mapping_on_one_line(tmp_path: Path) -> None:
    path = tmp_path / "twice.yaml"
    path.write_text("name: x\nframes: [{distance_km: 1, distance_km: 2}]\n", encoding="utf-8")
    with pytest.raises(SatsightError, match="key 'distance_km' given twice, on line 2;"):
        load_scenario(path)


def test_keys_equal_only_in_python_are_not_duplicates(tmp_path: Path) -> None:
    """``1``, ``1.0`` and ``true`` compare equal in Python but are different YAML keys."""
    path = tmp_path / "keys.yaml"
    path.write_text("1: a\n1.0: b\ntrue: c\n'1': d\n", encoding="utf-8")
    data = load_yaml_file(path)  # no error; the dict itself still merges them, as PyYAML does
    assert data == {1: "c", "1": "d"}


def test_alias_bomb_is_refused_quickly_and_small(tmp_path: Path) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text("name: x\nbomb:\n" + _laughs("  ") + "frames: *a8\n", encoding="utf-8")
    tracemalloc.start()
    start = time.perf_counter()
    try:
        with pytest.raises(SatsightError, match="aliases expanded") as info:
            load_scenario(path)
        seconds = time.perf_counter() - start
        _, peak_bytes = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert seconds < 2.0
    assert peak_bytes < 10e6
    assert "\n" not in str(info.value)


def test_ordinary_anchors_aliases_and_merge_keys_still_work(tmp_path: Path) -> None:
    path = tmp_path / "reuse.yaml"
    path.write_text(
        "name: reuse\n"
        "target: {procedural: {satellite_class: two_wings}}\n"
        "frames:\n"
        "  - &near {distance_km: 1.0, azimuth_deg: 10.0}\n"
        "  - *near\n"
        "  - <<: *near\n"
        "    azimuth_deg: 20.0\n"
        "  - {<<: *near, roll_deg: 30.0}\n",
        encoding="utf-8",
    )
    frames = load_scenario(path).frames
    assert frames[1] == frames[0]
    assert (frames[2].distance_km, frames[2].azimuth_deg) == (1.0, 20.0)
    assert (frames[3].azimuth_deg, frames[3].roll_deg) == (10.0, 30.0)


def test_limits_are_inclusive(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """MAX_DEPTH levels, MAX_ALIASES aliases and MAX_FILE_BYTES bytes are allowed; one more
    is refused."""
    path = tmp_path / "limits.yaml"
    path.write_text("[" * MAX_DEPTH + "]" * MAX_DEPTH, encoding="utf-8")
    load_yaml_file(path)
    path.write_text("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), encoding="utf-8")
    with pytest.raises(SatsightError, match=f"nested more than {MAX_DEPTH} levels"):
        load_yaml_file(path)

    path.write_text("- &a 1\n" + "- *a\n" * MAX_ALIASES, encoding="utf-8")
    assert len(load_yaml_file(path)) == MAX_ALIASES + 1
    path.write_text("- &a 1\n" + "- *a\n" * (MAX_ALIASES + 1), encoding="utf-8")
    with pytest.raises(SatsightError, match=f"more than {MAX_ALIASES} aliases"):
        load_yaml_file(path)

    monkeypatch.setattr(yaml_safety, "MAX_FILE_BYTES", 100)
    path.write_text("a: " + "x" * 97, encoding="utf-8")
    load_yaml_file(path)
    path.write_text("a: " + "x" * 98, encoding="utf-8")
    with pytest.raises(SatsightError, match="larger than"):
        load_yaml_file(path)


def test_alias_values_count_towards_the_expanded_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(yaml_safety, "MAX_NODES", 40)
    path = tmp_path / "grow.yaml"
    anchor = "a: &a [" + ", ".join(["x"] * 10) + "]\n"  # root, key, list of 10: 13 values
    path.write_text(anchor + "b: [*a, *a]\n", encoding="utf-8")  # 13 + key, list, 2 x 11: 37
    load_yaml_file(path)
    path.write_text(anchor + "b: [*a, *a, *a]\n", encoding="utf-8")  # 48
    with pytest.raises(SatsightError, match="more than 40 values"):
        load_yaml_file(path)


def test_recursion_error_is_a_message_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Should the depth limit ever be lifted, Python's own limit still ends in a message."""
    monkeypatch.setattr(yaml_safety, "MAX_DEPTH", 10**6)
    path = tmp_path / "deep.yaml"
    path.write_text("[" * 5000 + "]" * 5000, encoding="utf-8")
    with pytest.raises(SatsightError, match="nested too deeply to read"):
        load_yaml_file(path)


def test_a_fifo_or_a_dangling_link_is_not_read(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    with pytest.raises(SatsightError, match="not a regular file"):
        load_scenario(fifo)  # returns at once: a FIFO with no writer is never opened
    dangling = tmp_path / "dangling.yaml"
    dangling.symlink_to(tmp_path / "gone.yaml")
    with pytest.raises(SatsightError, match="symbolic link"):
        load_scenario(dangling)


def test_long_values_in_validation_messages_are_cut(tmp_path: Path) -> None:
    path = tmp_path / "long.yaml"
    path.write_text(
        "name: [" + ", ".join(["x"] * 5000) + "]\nframes: [" + ", ".join(["1"] * 200) + "]\n",
        encoding="utf-8",
    )
    with pytest.raises(SatsightError, match="the scenario is not valid:") as info:
        load_scenario(path)
    lines = str(info.value).splitlines()
    assert max(len(line) for line in lines) < 400
    assert lines[-1].startswith("  ... and ") and lines[-1].endswith(" more")


EXAMPLES = sorted(
    p.name for p in Path(str(resources.files("satsight") / "examples")).glob("*.yaml")
)


@pytest.mark.parametrize("name", EXAMPLES)
def test_bundled_examples_still_load(name: str) -> None:
    path = Path(str(resources.files("satsight") / "examples" / name))
    assert load_scenario(path).name
