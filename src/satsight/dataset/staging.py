"""All-or-nothing output folders: a dataset appears complete or not at all."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from satsight.errors import SatsightError


def check_output_folder(out_dir: Path, overwrite: bool) -> None:
    """Refuse to write over an existing non-empty folder unless told to."""
    if out_dir.exists() and not out_dir.is_dir():
        raise SatsightError(f"output path {out_dir} exists and is not a folder")
    if out_dir.is_dir() and any(out_dir.iterdir()) and not overwrite:
        raise SatsightError(
            f"output folder {out_dir} is not empty; choose another or pass --overwrite"
        )


@contextmanager
def staged_folder(out_dir: Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary folder beside ``out_dir``; on success it replaces ``out_dir``.

    On any error the temporary folder is removed and ``out_dir`` is left as it was, so a
    failed or interrupted run never leaves a half-written dataset.
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
        if out_dir.exists():
            out_dir.rename(old)
        staging.rename(out_dir)
    except OSError as error:
        if old.exists() and not out_dir.exists():
            old.rename(out_dir)
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
