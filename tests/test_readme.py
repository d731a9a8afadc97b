"""Every ```python block of README.md runs as written, each in a fresh empty folder and
namespace, so that the recipes cannot fall out of step with the code."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)


def python_blocks(text: str) -> list[tuple[int, str]]:
    """(first line number, code) of each ```python block of a Markdown text."""
    return [(text.count("\n", 0, m.start(1)) + 1, m.group(1)) for m in _BLOCK.finditer(text)]


BLOCKS = python_blocks(README.read_text(encoding="utf-8"))


def run_block(code: str, name: str) -> None:
    exec(compile(code, name, "exec"), {"__name__": "__main__"})


def test_the_readme_has_recipes() -> None:
    assert len(BLOCKS) >= 2


def test_block_extraction_and_a_failing_block_fails(tmp_path: Path) -> None:
    text = "a\n```python\nx = 1\n```\n```sh\nls\n```\n```python\nraise ValueError('no')\n```\n"
    blocks = python_blocks(text)
    assert blocks == [(3, "x = 1\n"), (9, "raise ValueError('no')\n")]
    run_block(blocks[0][1], "first")
    with pytest.raises(ValueError, match="no"):
        run_block(blocks[1][1], "second")


@pytest.mark.parametrize(("line", "code"), BLOCKS, ids=[f"line{line}" for line, _ in BLOCKS])
def test_readme_block_runs(line: int, code: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    # Blank lines in front, so that a traceback gives the README's line numbers.
    run_block("\n" * (line - 1) + code, str(README))
