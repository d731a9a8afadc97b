"""The folder a run writes: its manifest, starting, resuming or replacing it, the files
written once per start, and file system errors said in one line."""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import yaml

from satsight.config.scenario import Scenario
from satsight.config.yaml_safety import load_yaml_file
from satsight.dataset.journal import write_bytes_atomic
from satsight.dataset.lock import folder_entries
from satsight.dataset.manifest import manifest_document, scenario_sha256, write_manifest
from satsight.dataset.reader import COMPLETE_NAME, MANIFEST_NAME, read_json
from satsight.dataset.staging import check_dataset_folder
from satsight.errors import SatsightError
from satsight.pipeline import FrameEngine
from satsight.run.shard import Shard
from satsight.scene.obj_export import write_obj


def scenario_json(scenario: Scenario) -> dict:
    """The scenario as a JSON document (what scenario.yaml holds and the manifest hashes)."""
    return scenario.model_dump(mode="json")


def dataset_manifest(engine: FrameEngine, shard: Shard | None) -> dict:
    """The manifest of the dataset a scenario makes (for one shard of it, or whole)."""
    header = engine.header()
    return manifest_document(
        {
            **header,
            "scenario_sha256": scenario_sha256(scenario_json(engine.scenario)),
            "shard": None if shard is None else shard.label(),
        }
    )


def _differences(stored: dict, current: dict, prefix: str = "") -> list[str]:
    """Dotted keys whose values differ between two JSON documents."""
    keys = []
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key), current.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            keys += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            keys.append(f"{prefix}{key}")
    return keys


def _check_same_dataset(root: Path, manifest: dict, scenario: Scenario) -> None:
    """Refuse to resume a folder that holds another scenario's (or version's) dataset."""
    stored = read_json(root / MANIFEST_NAME)
    if stored == manifest:
        return
    if stored.get("scenario_sha256") != manifest["scenario_sha256"]:
        try:
            old = load_yaml_file(root / "scenario.yaml")  # the folder may not be ours
            keys = _differences(old if isinstance(old, dict) else {}, scenario_json(scenario))
        except SatsightError:
            keys = []
        where = f" (differs in {', '.join(keys[:6])})" if keys else ""
        raise SatsightError(
            f"{root} holds a dataset of another scenario{where}; resume with the scenario "
            "and options it was started with, or choose another folder"
        )
    keys = _differences(stored, manifest)
    raise SatsightError(
        f"{root} was started with different settings ({', '.join(keys[:6])}); resume with "
        "what it was started with (the same mesh file, satsight version, shard and render "
        "variant), or choose another folder"
    )


_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO,
                 errno.EFBIG}  # fmt: skip


@contextmanager
def write_errors_teach(out_dir: Path) -> Iterator[None]:
    """A file system error while the dataset is written becomes one line that names the
    file and says what to do (every committed frame is kept)."""
    try:
        yield
    except SatsightError:
        raise
    except OSError as error:
        path = error.filename or out_dir
        what = "could not write" if error.errno in _WRITE_ERRNOS else "could not use"
        raise SatsightError(
            f"{what} {path}: {error.strerror or error}; the frames committed so far are "
            "kept: free space or fix the folder, then run again with --resume"
        ) from None


def remove_temporary_files(root: Path) -> None:
    """Delete files a killed run left under temporary names (``.NAME.tmp-PID``)."""
    for folder, _, names in os.walk(root):
        for name in names:
            if name.startswith(".") and ".tmp-" in name:
                Path(folder, name).unlink(missing_ok=True)


def prepare_folder(
    out_dir: Path, manifest: dict, scenario: Scenario, overwrite: bool, resume: bool
) -> bool:
    """Make ``out_dir`` ready for the run; True when it already holds a complete dataset.

    A new or empty folder is started; an existing dataset is resumed (``resume``, same
    manifest) or replaced (``overwrite``); anything else is refused before any writing.
    """
    out_dir = Path(out_dir)
    check_dataset_folder(out_dir, overwrite, resume)  # again: the folder may have changed
    if entries := folder_entries(out_dir):  # a dataset (checked above)
        if overwrite:  # all but this run's lock file
            for entry in entries:
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
        else:  # resume
            _check_same_dataset(out_dir, manifest, scenario)
            return (out_dir / COMPLETE_NAME).is_file()
    out_dir.mkdir(parents=True, exist_ok=True)
    write_manifest(out_dir, manifest)
    return False


def write_dataset_files(root: Path, engine: FrameEngine) -> None:
    """scenario.yaml and the model: rewritten on every start (same bytes each time)."""
    write_bytes_atomic(
        root / "scenario.yaml",
        yaml.safe_dump(scenario_json(engine.scenario), sort_keys=False).encode("utf-8"),
    )
    (root / "model").mkdir(exist_ok=True)
    write_obj(engine.mesh, root / "model" / "target.obj")
