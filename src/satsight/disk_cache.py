"""What satsight computes once and keeps between runs, under ``$XDG_CACHE_HOME/satsight``
(default ``~/.cache/satsight``): the Earth's albedo maps, the land mask's ocean counts, the
material library's computed spectra. Files are written whole under a temporary name and
renamed into place, so concurrent processes see a whole file or none; a damaged or
unreadable file counts as missing and is built again."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def cache_dir() -> Path:
    """The folder of satsight's cached files (not created here)."""
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(root) / "satsight"


def write_npz_atomically(path: Path, **arrays: np.ndarray) -> None:
    """Write a compressed .npz under a temporary name and rename it into place, so that a
    concurrent reader sees the whole file or none."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".npz", delete=False) as f:
        np.savez_compressed(f, **arrays)
    os.replace(f.name, path)


def read_npz(path: Path, *names: str) -> dict[str, np.ndarray] | None:
    """The arrays ``names`` of the .npz at ``path``, or None when it is missing, damaged or
    lacks one of them."""
    if not path.exists():
        return None
    try:
        with np.load(path) as data:
            return {name: data[name] for name in names}
    except (OSError, ValueError, KeyError, EOFError):
        return None
