"""The library's computed spectra kept on disk: a cached spectrum is the computed one bit
for bit, a damaged cache file is built again, and a new process reads the cache."""

from __future__ import annotations

import numpy as np
import pytest

from satsight.scene import material_library
from satsight.scene.material_library import compute_spectrum, entry_spectrum, load_entry
from satsight.scene.spectra import wavelength_grid_nm

COMPUTED = "mli_aluminised_kapton"  # a thin-film stack on a substrate


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """An empty cache folder, and no spectrum kept in this process."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(material_library, "_SPECTRUM_CACHE", {})
    return tmp_path / "satsight"


def test_a_cached_spectrum_is_the_computed_one_bit_for_bit(fresh_cache, monkeypatch) -> None:
    entry = load_entry(COMPUTED)
    assert entry.computed is not None
    expected = compute_spectrum(entry.computed, wavelength_grid_nm())
    _, first = entry_spectrum(entry)
    (path,) = fresh_cache.glob(f"spectrum_{COMPUTED}_*.npz")
    assert first.tobytes() == expected.tobytes()
    # Another process: nothing in memory, and computing is not allowed.
    monkeypatch.setattr(material_library, "_SPECTRUM_CACHE", {})

    def refuse(*args):
        raise AssertionError("computed again although the cache holds it")

    monkeypatch.setattr(material_library, "compute_spectrum", refuse)
    _, again = entry_spectrum(entry)
    assert again.tobytes() == expected.tobytes()
    assert path.exists()


def test_a_damaged_cache_file_is_built_again(fresh_cache, monkeypatch) -> None:
    entry = load_entry(COMPUTED)
    _, first = entry_spectrum(entry)
    (path,) = fresh_cache.glob(f"spectrum_{COMPUTED}_*.npz")
    path.write_bytes(b"not a zip file")
    monkeypatch.setattr(material_library, "_SPECTRUM_CACHE", {})
    _, rebuilt = entry_spectrum(entry)
    assert rebuilt.tobytes() == first.tobytes()
    with np.load(path) as data:
        assert data["reflectance"].tobytes() == first.tobytes()
