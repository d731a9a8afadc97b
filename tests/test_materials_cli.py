"""`satsight materials`: the library's table, its JSON and its figure, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cli_runner import run_satsight
from satsight.scene.band_reflectance import material_rgb_reflectance
from satsight.scene.material_library import load_library


def test_materials_lists_every_library_entry_with_its_band_reflectance(tmp_path: Path) -> None:
    result = run_satsight(
        "materials", "--band", "500,800", "--qe", "flat", "--out", "m", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    document = json.loads((tmp_path / "m" / "materials.json").read_text(encoding="utf-8"))
    assert document["band_nm"] == [500.0, 800.0] and document["quantum_efficiency"] == "flat"
    library = load_library()
    rows = {row["name"]: row for row in document["materials"]}
    assert set(rows) == set(library) and len(rows) >= 16
    for name, row in rows.items():
        # The table rounds to 3 decimals: the band integration of the same entry.
        expected = material_rgb_reflectance(library[name], (500.0, 800.0), "flat")
        assert row["rgb"] == pytest.approx(expected, abs=5e-4)
        assert name in result.stdout
    assert (tmp_path / "m" / "material_spectra.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--band", "900,450"], "0 < lo < hi"),
        (["--band", "450"], "--band must be two wavelengths"),
        (["--qe", "nope"], "Invalid value for '--qe'"),
    ],
)
def test_bad_options_exit_2_with_a_message(tmp_path: Path, args, message) -> None:
    result = run_satsight("materials", *args, "--out", "m", cwd=tmp_path)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "m").exists()
