"""Procedural satellites kept on disk (scene/procedural_cache.py): the kept mesh is the
built one, array for array; a second run reads it without building; a damaged file, other
arguments or other code build anew; a cache that cannot be written only costs the build;
and checking a scenario loads none of the mesh tools."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from satsight.scene import procedural, procedural_cache
from satsight.scene.band_reflectance import builtins_from_library

BAND_NM = (450.0, 900.0)
ARGS = ("two_wings_dish", 3, True, True, BAND_NM)


@pytest.fixture
def cache_home(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    return tmp_path / "satsight" / "procedural"


def _equal(x, y) -> None:
    """Equal values: arrays element for element, dataclasses field by field."""
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        np.testing.assert_array_equal(x, y)
    elif dataclasses.is_dataclass(x) and not isinstance(x, type):
        assert type(x) is type(y)
        for field in dataclasses.fields(x):
            _equal(getattr(x, field.name), getattr(y, field.name))
    elif isinstance(x, (tuple, list)):
        assert len(x) == len(y)
        for u, v in zip(x, y, strict=True):
            _equal(u, v)
    else:
        assert x == y


def _same(a, b) -> None:
    """Two meshes hold equal arrays, names, textures and materials of their parts."""
    for field in dataclasses.fields(a):
        x, y = getattr(a, field.name), getattr(b, field.name)
        if field.name == "materials":
            used = set(a.part_materials)
            assert {k: x[k] for k in used} == {k: y[k] for k in used}
        else:
            _equal(x, y)


def test_the_kept_mesh_is_the_built_one_and_is_read_back_without_building(
    cache_home: Path, monkeypatch
) -> None:
    built = procedural.generate_satellite(
        "two_wings_dish", 3, smooth_normals=True, textures=True,
        materials=builtins_from_library(BAND_NM),
    )  # fmt: skip
    first = procedural_cache.satellite(*ARGS)
    assert len(list(cache_home.glob("*.pkl"))) == 1
    _same(first, built)

    def no_build(*args, **kwargs):
        raise AssertionError("built again")

    monkeypatch.setattr(procedural, "generate_satellite", no_build)
    _same(procedural_cache.satellite(*ARGS), built)


def test_a_damaged_file_other_arguments_or_other_code_build_anew(
    cache_home: Path, monkeypatch
) -> None:
    path = procedural_cache.cache_path(*ARGS)
    procedural_cache.satellite(*ARGS)
    path.write_bytes(path.read_bytes()[:100])  # cut short
    calls = []
    build = procedural.generate_satellite
    monkeypatch.setattr(
        procedural, "generate_satellite", lambda *a, **k: calls.append(a) or build(*a, **k)
    )
    procedural_cache.satellite(*ARGS)
    assert len(calls) == 1
    others = [
        ("two_wings_dish", 4, True, True, BAND_NM),
        ("two_wings_dish", 3, False, True, BAND_NM),
        ("two_wings_dish", 3, True, False, BAND_NM),
        ("two_wings_dish", 3, True, True, None),
        ("two_wings_dish", 3, True, True, (500.0, 800.0)),
    ]
    paths = {procedural_cache.cache_path(*args) for args in others}
    assert len(paths) == len(others) and path not in paths
    monkeypatch.setattr(procedural_cache, "code_stamp", lambda: "another version")
    assert procedural_cache.cache_path(*ARGS) != path


def test_a_cache_that_cannot_be_written_only_costs_the_build(tmp_path: Path, monkeypatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))  # cache_dir() cannot be made
    mesh = procedural_cache.satellite("two_wings", 1, False, False, None)
    _same(mesh, procedural.generate_satellite("two_wings", 1))


def test_checking_a_scenario_loads_no_mesh_tools() -> None:
    """The scenario's modules leave trimesh (0.6 s with the parts of scipy it loads) to the
    builds that need it."""
    code = "import sys, satsight.config.scenario; print('trimesh' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
