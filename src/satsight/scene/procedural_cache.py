"""Procedural satellites and replicas kept on disk between runs, so that a scenario's
target costs a file read instead of its construction and the mesh tools' import (0.2 s
and 0.6 s for the RSSF example's satellite on a 2-core machine, against 1 ms).

A cached mesh lives under ``disk_cache.cache_dir() / "procedural"``, named by the SHA-256
of what makes it: the class, seed, surfaces, materials (built-in, or the library's over a
band) and a stamp of satsight's installed files (their paths, sizes and modification
times), so that any change to the code or its data builds it anew. It is a pickle of the
``TargetMesh``: a file in the user's own cache, read as satsight's own data. A missing,
damaged or unreadable file is built again; a cache folder that cannot be written is
skipped.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import tempfile
from functools import cache
from pathlib import Path

from satsight.disk_cache import cache_dir
from satsight.scene.mesh import TargetMesh

_FORMAT = 1


@cache
def code_stamp() -> str:
    """SHA-256 of the relative path, size and modification time of every file of the
    installed satsight package (bytecode caches left out)."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if "__pycache__" in path.parts or not path.is_file():
            continue
        stat = path.stat()
        digest.update(f"{path.relative_to(root)}\0{stat.st_size}\0{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()


def cache_path(
    satellite_class: str,
    seed: int,
    smooth_normals: bool,
    textures: bool,
    band_nm: tuple[float, float] | None,
) -> Path:
    """Where the mesh of these arguments is kept (``satellite``)."""
    what = [_FORMAT, code_stamp(), satellite_class, int(seed), bool(smooth_normals),
            bool(textures), None if band_nm is None else [float(v) for v in band_nm]]  # fmt: skip
    key = hashlib.sha256(json.dumps(what).encode()).hexdigest()
    return cache_dir() / "procedural" / f"{satellite_class}-{key[:32]}.pkl"


def satellite(
    satellite_class: str,
    seed: int,
    smooth_normals: bool,
    textures: bool,
    band_nm: tuple[float, float] | None,
) -> TargetMesh:
    """``procedural.generate_satellite(satellite_class, seed, smooth_normals, textures,
    materials)``, from the disk when it was built before: materials are the spectral
    library's over ``band_nm`` (``band_reflectance.builtins_from_library``), or the
    built-in values when ``band_nm`` is None."""
    path = cache_path(satellite_class, seed, smooth_normals, textures, band_nm)
    try:
        with open(path, "rb") as stream:
            mesh = pickle.load(stream)
        if isinstance(mesh, TargetMesh):
            return mesh
    except Exception:  # missing, cut or unreadable: built again below
        pass
    from satsight.scene.band_reflectance import builtins_from_library
    from satsight.scene.procedural import generate_satellite

    mesh = generate_satellite(
        satellite_class,
        seed,
        smooth_normals=smooth_normals,
        textures=textures,
        materials=None if band_nm is None else builtins_from_library(band_nm),
    )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".pkl", delete=False) as f:
            pickle.dump(mesh, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(f.name, path)
    except OSError:
        pass  # a cache that cannot be written: the mesh is built each time
    return mesh
