"""All-or-nothing output folders: a dataset appears complete or not at all."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from satsight.dataset.lock import LOCK_NAME, folder_entries, refuse_if_locked
from satsight.errors import SatsightError


def check_output_folder(out_dir: Path, overwrite: bool) -> None:
    """Refuse to write over an existing non-empty folder unless told to (a writer's lock
    file alone leaves a folder empty)."""
    if out_dir.exists() and not out_dir.is_dir():
        raise SatsightError(f"output path {out_dir} exists and is not a folder")
    if folder_entries(out_dir) and not overwrite:
        raise SatsightError(
            f"output folder {out_dir} is not empty; choose another or pass --overwrite"
        )


def check_dataset_folder(out_dir: Path, overwrite: bool, resume: bool) -> None:
    """Refuse, before the scenario's heavy parts load, an output folder a dataset run
    (generate, demo) cannot use: a file, the current folder or one of its parents, a place
    that cannot be created or written in, a non-empty folder that holds no satsight dataset,
    or a dataset without ``overwrite`` or ``resume``. Whether a dataset to resume holds the
    same scenario is checked later, against the run's manifest. A folder another process
    is writing is refused first, naming that process."""
    from satsight.dataset.journal import journal_frames
    from satsight.dataset.reader import COMPLETE_NAME, is_dataset

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise SatsightError(f"output path {out_dir} exists and is not a folder")
    resolved = out_dir.resolve()
    if resolved == Path(resolved.anchor) or Path.cwd().is_relative_to(resolved):
        raise SatsightError(
            f"output folder {out_dir} is the current folder or one of its parents; "
            "choose a folder of its own"
        )
    existing = next(p for p in (resolved, *resolved.parents) if p.exists())
    if not existing.is_dir():
        raise SatsightError(f"cannot create the output folder {out_dir}: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise SatsightError(
            f"cannot write in {existing} (permission denied); choose another output folder"
        )
    refuse_if_locked(out_dir)
    if not folder_entries(out_dir):
        return
    if not is_dataset(out_dir):
        raise SatsightError(
            f"output folder {out_dir} is not empty and holds no satsight dataset "
            "(--overwrite replaces only satsight datasets); choose an empty or new folder"
        )
    if overwrite or resume:
        return
    if (out_dir / COMPLETE_NAME).is_file():
        raise SatsightError(
            f"output folder {out_dir} holds a complete dataset; pass --overwrite to "
            "replace it, or choose another folder"
        )
    committed = len(journal_frames(out_dir))
    raise SatsightError(
        f"output folder {out_dir} holds an incomplete dataset ({committed} frames "
        "committed); pass --resume to finish it or --overwrite to replace it"
    )


@contextmanager
def staged_folder(out_dir: Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary folder beside ``out_dir``; on success it replaces ``out_dir``.

    On any error the temporary folder is removed and ``out_dir`` is left as it was, so a
    failed or interrupted run never leaves a half-written dataset. A writer's lock file in
    ``out_dir`` moves into the new folder (its lock held throughout).
    """
    out_dir = Path(out_dir).resolve()
    if out_dir == Path(out_dir.anchor) or Path.cwd().is_relative_to(out_dir):
        raise SatsightError(
            f"output folder {out_dir} is the current folder or one of its parents; "
            "choose a folder of its own"
        )
    check_output_folder(out_dir, overwrite)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.partial-", dir=out_dir.parent))
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    _apply_umask(staging)
    old = out_dir.with_name(f".{out_dir.name}.old-{staging.name.rsplit('-', 1)[-1]}")
    try:
        if (out_dir / LOCK_NAME).is_file():
            os.replace(out_dir / LOCK_NAME, staging / LOCK_NAME)
        if out_dir.exists():
            out_dir.rename(old)
        staging.rename(out_dir)
    except OSError as error:
        if old.exists() and not out_dir.exists():
            old.rename(out_dir)
        if (staging / LOCK_NAME).is_file() and out_dir.is_dir():
            os.replace(staging / LOCK_NAME, out_dir / LOCK_NAME)
        shutil.rmtree(staging, ignore_errors=True)
        raise SatsightError(
            f"could not move the finished dataset into {out_dir}: {error}"
        ) from None
    shutil.rmtree(old, ignore_errors=True)


def _apply_umask(folder: Path) -> None:
    """Give the staging folder (created 0700 by mkdtemp) the permissions of a new folder."""
    umask = os.umask(0)
    os.umask(umask)
    folder.chmod(0o777 & ~umask)
