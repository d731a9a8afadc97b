"""Dataset writing integrity: merge --move never loses a shard file, --resume checks the
files it keeps (and repairs a complete dataset), and every write error is one line that
leaves only whole, committed frames behind, which --resume finishes byte for byte."""

from __future__ import annotations

import errno
import hashlib
import os
import re
import shutil
from pathlib import Path

import pytest

import satsight.dataset.image_files as image_files
import satsight.dataset.journal as journal
import satsight.dataset.manifest as manifest
import satsight.dataset.merge as merge
from dataset_files import file_hashes, generated_dataset, views_scenario, write_scenario_yaml
from satsight.cli import main
from satsight.config.scenario import parse_scenario
from satsight.dataset.journal import read_journal
from satsight.dataset.lock import LOCK_NAME
from satsight.dataset.validate import validate_dataset
from satsight.run.generation import generate_dataset
from satsight.run.shard import Shard

FRAME_COUNT = 6


def scenario_dict() -> dict:
    return views_scenario(
        "integrity-test", 3, FRAME_COUNT, (96, 64), 0.003, (37.0, 17, 70, 11.0), 2
    )


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory) -> Path:
    return write_scenario_yaml(tmp_path_factory.mktemp("scenario"), scenario_dict())


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The dataset of an uninterrupted run."""
    return generated_dataset(tmp_path_factory.mktemp("reference") / "dataset", scenario_dict())


@pytest.fixture(scope="module")
def reference_hashes(reference: Path) -> dict[str, str]:
    return file_hashes(reference)


@pytest.fixture(scope="module")
def shard_pair(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("shards")
    scenario = parse_scenario(scenario_dict())
    folders = [root / f"shard{k + 1}" for k in range(2)]
    for k, folder in enumerate(folders):
        assert generate_dataset(scenario, folder, shard=Shard(k, 2)).complete
    return folders


def run_cli(capsys, *args: str) -> tuple[int, str]:
    """``satsight ARGS`` in this process (so that a test can patch its file writes): the
    exit status and standard error."""
    capsys.readouterr()
    try:
        main([str(a) for a in args])
        status = 0
    except SystemExit as end:
        status = end.code
    return status, capsys.readouterr().err


def one_error_line(stderr: str) -> str:
    """The one error line that ends a command's output (after its header and progress)."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert "Traceback" not in stderr
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1 and lines[-1] == errors[0], stderr
    assert all(line.startswith(("satsight: scenario", "frames ")) for line in lines[:-1])
    return errors[0]


def leftovers(root: Path) -> list[Path]:
    """Temporary files, staging folders and lock files under and beside ``root``."""
    beside = [p for p in root.parent.iterdir() if p.name.startswith(f".{root.name}.")]
    inside = [p for p in root.rglob(".*") if ".tmp-" in p.name or p.name == LOCK_NAME]
    return beside + (inside if root.is_dir() else [])


# --- merge --move -------------------------------------------------------------------------
@pytest.fixture
def shards(tmp_path: Path, shard_pair: list[Path]) -> list[Path]:
    copies = [tmp_path / folder.name for folder in shard_pair]
    for folder, copy in zip(shard_pair, copies, strict=True):
        shutil.copytree(folder, copy)
    return copies


def test_merge_move_with_a_missing_shard_file_moves_nothing(
    tmp_path: Path, shards: list[Path], capsys
) -> None:
    (shards[1] / "images" / "frame_000003.png").unlink()
    before = [file_hashes(folder) for folder in shards]
    out = tmp_path / "merged"
    status, stderr = run_cli(capsys, "merge", *shards, "--out", out, "--move")
    assert status == 2
    line = one_error_line(stderr)
    assert "frame 3's file images/frame_000003.png is missing" in line
    assert "nothing was moved" in line and "--shard 2/2 --resume" in line
    assert [file_hashes(folder) for folder in shards] == before
    assert not out.exists() and not leftovers(out)


@pytest.mark.parametrize("failing", ["link", "copy"])
def test_merge_move_that_fills_the_disk_midway_leaves_every_shard_file(
    tmp_path: Path, shards: list[Path], reference_hashes, monkeypatch, capsys, failing: str
) -> None:
    """The disk fills at the 7th file: linked (same file system) or copied (links
    impossible, as across file systems)."""
    real_link, real_copy = os.link, shutil.copyfile
    placed = []

    def full_after_six(source, target):
        if len(placed) == 6:
            raise OSError(errno.ENOSPC, "No space left on device", str(target))
        placed.append(target)

    def link(source, target, **kwargs):
        if failing == "copy":
            raise OSError(errno.EXDEV, "Invalid cross-device link")
        full_after_six(source, target)
        return real_link(source, target, **kwargs)

    def copyfile(source, target, **kwargs):
        full_after_six(source, target)
        return real_copy(source, target, **kwargs)

    monkeypatch.setattr(merge.os, "link", link)
    monkeypatch.setattr(merge.shutil, "copyfile", copyfile)
    before = [file_hashes(folder) for folder in shards]
    out = tmp_path / "merged"
    status, stderr = run_cli(capsys, "merge", *shards, "--out", out, "--move")
    assert status == 2 and len(placed) == 6
    line = one_error_line(stderr)
    assert "No space left on device" in line and "shards are as they were" in line
    assert [file_hashes(folder) for folder in shards] == before
    assert not out.exists() and not leftovers(out)

    monkeypatch.undo()  # space freed: the same command merges and moves
    status, stderr = run_cli(capsys, "merge", *shards, "--out", out, "--move")
    assert status == 0, stderr
    assert file_hashes(out) == reference_hashes
    for folder in shards:
        assert not list((folder / "images").iterdir())


def test_merge_into_a_folder_being_written_is_refused(
    tmp_path: Path, shards: list[Path], capsys
) -> None:
    from satsight.dataset.lock import WriterLock

    out = tmp_path / "merged"
    with WriterLock(out):
        status, stderr = run_cli(capsys, "merge", *shards, "--out", out)
        assert status == 2
        line = one_error_line(stderr)
        assert f"being written by another satsight process (pid {os.getpid()} on" in line
    assert not out.exists()


# --- resume checks what it keeps ----------------------------------------------------------
def _overwrite_64_bytes(path: Path) -> None:
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = bytes(64)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("complete", [True, False], ids=["complete", "incomplete"])
@pytest.mark.parametrize(
    "damage",
    ["missing png", "changed png", "changed exr"],
)
def test_resume_renders_again_frames_whose_files_are_missing_or_changed(
    tmp_path: Path, reference: Path, reference_hashes, capsys, scenario_file: Path,
    caplog, damage: str, complete: bool,
) -> None:  # fmt: skip
    out = tmp_path / "dataset"
    shutil.copytree(reference, out)
    if not complete:
        for name in ("complete.json", "labels.json", "contact_sheet.png"):
            (out / name).unlink()
    target = {
        "missing png": out / "images" / "frame_000002.png",
        "changed png": out / "images" / "frame_000002.png",
        "changed exr": out / "depth" / "frame_000002.exr",
    }[damage]
    size = target.stat().st_size
    if damage.startswith("missing"):
        target.unlink()
    else:
        _overwrite_64_bytes(target)
        assert target.stat().st_size == size
    status, stderr = run_cli(capsys, "generate", scenario_file, "--out", out, "--resume")
    assert status == 0, stderr
    assert "already complete" not in stderr
    assert "wrote 1 frames" in stderr and f"{FRAME_COUNT - 1} were there" in stderr
    assert "frame 2: " in caplog.text and "missing or changed" in caplog.text
    assert file_hashes(out) == reference_hashes


def test_resume_of_an_intact_complete_dataset_writes_nothing(
    tmp_path: Path, reference: Path, reference_hashes, scenario_file: Path, capsys
) -> None:
    out = tmp_path / "dataset"
    shutil.copytree(reference, out)
    mtimes = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    status, stderr = run_cli(capsys, "generate", scenario_file, "--out", out, "--resume")
    assert status == 0 and "already complete" in stderr
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == mtimes
    assert file_hashes(out) == reference_hashes


# --- write errors -------------------------------------------------------------------------
class _FailingExr:
    """OpenEXR with ``File.write`` failing as it does on a full disk, for one frame."""

    def __init__(self, stem: str):
        self._stem = stem

    def __getattr__(self, name):
        return getattr(_REAL_OPENEXR, name)

    def File(self, *args):
        real = _REAL_OPENEXR.File(*args)
        stem = self._stem

        class Writer:
            def __enter__(self):
                real.__enter__()
                return self

            def __exit__(self, *exc):
                return real.__exit__(*exc)

            def write(self, path):
                if stem in path:
                    Path(path).write_bytes(b"\x76\x2f\x31\x01 half an EXR")
                    raise RuntimeError(f"Failed to write pixel data to image file '{path}'")
                return real.write(path)

        return Writer()


_REAL_OPENEXR = image_files.OpenEXR


def _fail_png_write(monkeypatch, stem: str) -> None:
    """The disk fills while a PNG of frame ``stem`` is written (half its bytes land)."""
    real = Path.write_bytes

    def write_bytes(self, data):
        if stem in self.name and ".png" in self.name:
            real(self, data[: len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device", str(self))
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", write_bytes)


def _fail_labels_json(monkeypatch) -> None:
    """The disk fills while labels.json is written, at the end of the run."""
    real = journal.write_lines_atomic

    def write_lines_atomic(path, lines):
        if Path(path).name != "labels.json":
            return real(path, lines)

        def some_then_full():
            for number, line in enumerate(lines):
                if number == 3:
                    raise OSError(errno.ENOSPC, "No space left on device", str(path))
                yield line

        return real(path, some_then_full())

    monkeypatch.setattr(manifest, "write_lines_atomic", write_lines_atomic)


def _fail_journal_line(monkeypatch) -> None:
    """The disk fills while frame 3's journal line is appended (half of it lands)."""
    real = journal.JournalWriter.append

    def append(self, record):
        if record["frame_index"] == 3:
            line = journal.record_line(record)
            self._stream.write(line[: len(line) // 2])
            self._stream.flush()
            raise OSError(errno.ENOSPC, "No space left on device", str(self.path))
        return real(self, record)

    monkeypatch.setattr(journal.JournalWriter, "append", append)


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("exr", r"could not write \S*depth/frame_000003\.exr: OpenEXR could not write the "
                r"file \(Failed to write pixel data\)"),
        ("exr, disk full", r"could not write \S*/frame_000003\.exr: No space left on device"),
        ("png", r"could not write \S*/frame_000003\S*\.png: No space left on device"),
        ("labels.json", r"could not write \S*labels\.json: No space left on device"),
        ("journal", r"could not write \S*journal\.jsonl: No space left on device"),
    ],
)  # fmt: skip
def test_a_write_error_is_one_line_and_resume_finishes_byte_for_byte(
    tmp_path: Path, scenario_file: Path, reference_hashes, monkeypatch, capsys,
    case: str, message: str,
) -> None:  # fmt: skip
    if case.startswith("exr"):
        monkeypatch.setattr(image_files, "OpenEXR", _FailingExr("depth/.frame_000003"))
        if case == "exr, disk full":
            free = shutil.disk_usage("/")._replace(free=1 << 20)
            monkeypatch.setattr(image_files.shutil, "disk_usage", lambda path: free)
    elif case == "png":
        _fail_png_write(monkeypatch, "frame_000003")
    elif case == "labels.json":
        _fail_labels_json(monkeypatch)
    else:
        _fail_journal_line(monkeypatch)
    out = tmp_path / "dataset"
    status, stderr = run_cli(capsys, "generate", scenario_file, "--out", out)
    assert status == 2
    line = one_error_line(stderr)
    assert re.search(message, line), line
    assert "--resume" in line
    # Nothing half-written is committed: every journal record's files are whole.
    assert not (out / "complete.json").exists()
    assert not leftovers(out)
    committed = read_journal(out)
    if case != "labels.json":
        assert 3 not in {r["frame_index"] for r in committed}
    for record in committed:
        for relative, checksum in record["checksums"].items():
            data = (out / relative).read_bytes()
            assert hashlib.sha256(data).hexdigest() == checksum["sha256"]

    monkeypatch.undo()  # space freed
    status, stderr = run_cli(capsys, "generate", scenario_file, "--out", out, "--resume")
    assert status == 0, stderr
    assert file_hashes(out) == reference_hashes
    assert validate_dataset(out).ok
