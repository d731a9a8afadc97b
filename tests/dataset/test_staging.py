"""All-or-nothing output folders."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest

from satsight.dataset.staging import check_output_folder, staged_folder
from satsight.errors import SatsightError


class _Boom(RuntimeError):
    pass


def _listing(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): (p.read_text() if p.is_file() else "<dir>")
        for p in sorted(folder.rglob("*"))
    }


def test_success_moves_the_staging_folder_into_place(tmp_path: Path) -> None:
    out = tmp_path / "nested" / "dataset"
    with staged_folder(out) as root:
        assert root.parent == out.parent
        assert root.name.startswith(".dataset.partial-")
        assert not out.exists()  # nothing appears before the end
        (root / "labels.json").write_text("{}")
        (root / "images").mkdir()
        (root / "images" / "a.png").write_text("png")
    assert not root.exists()
    assert _listing(out) == {"images": "<dir>", "images/a.png": "png", "labels.json": "{}"}
    assert stat.S_IMODE(out.stat().st_mode) == 0o755
    assert sorted(p.name for p in out.parent.iterdir()) == ["dataset"]


def test_exception_leaves_neither_output_nor_partial_folder(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    with pytest.raises(_Boom), staged_folder(out) as root:
        (root / "labels.json").write_text("half")
        raise _Boom("render failed")
    assert not out.exists()
    assert not root.exists()
    assert list(tmp_path.iterdir()) == []


def test_keyboard_interrupt_also_cleans_up(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    with pytest.raises(KeyboardInterrupt), staged_folder(out) as root:
        (root / "frame.exr").write_text("x")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_existing_non_empty_folder_is_refused_without_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    out.mkdir()
    (out / "keep.txt").write_text("precious")
    with pytest.raises(SatsightError, match=r"not empty.*--overwrite"), staged_folder(out):
        pytest.fail("the body must not run")
    assert _listing(out) == {"keep.txt": "precious"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset"]


def test_overwrite_replaces_the_folder_and_removes_the_old_content(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    (out / "old_sub").mkdir(parents=True)
    (out / "old_sub" / "stale.png").write_text("stale")
    (out / "labels.json").write_text("old")
    with staged_folder(out, overwrite=True) as root:
        # The old dataset stays readable until the new one is complete.
        assert (out / "labels.json").read_text() == "old"
        (root / "labels.json").write_text("new")
    assert _listing(out) == {"labels.json": "new"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset"]


def test_failed_overwrite_keeps_the_old_folder(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    out.mkdir()
    (out / "labels.json").write_text("old")
    with pytest.raises(_Boom), staged_folder(out, overwrite=True) as root:
        (root / "labels.json").write_text("new")
        raise _Boom
    assert _listing(out) == {"labels.json": "old"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset"]


def test_existing_empty_folder_is_used_without_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    out.mkdir()
    with staged_folder(out) as root:
        (root / "a.txt").write_text("a")
    assert _listing(out) == {"a.txt": "a"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset"]


def test_output_path_that_is_a_file_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "dataset"
    out.write_text("a file")
    with pytest.raises(SatsightError, match="not a folder"):
        check_output_folder(out, overwrite=True)
    assert out.read_text() == "a file"


def test_check_output_folder_accepts_missing_and_empty(tmp_path: Path) -> None:
    check_output_folder(tmp_path / "missing", overwrite=False)
    (tmp_path / "empty").mkdir()
    check_output_folder(tmp_path / "empty", overwrite=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty"]
