"""Library materials in a scenario: ``target.mesh.materials: {part: "library:NAME"}``.

The part takes the library material with its colour integrated over the scenario's band,
so changing the band changes it the way the band integration says.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from satsight.config.scenario import TargetConfig
from satsight.scene.band_reflectance import material_from_entry

OBJ = """mtllib plate.mtl
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
o panel
usemtl grey
f 1 2 3
o foil
usemtl grey
f 2 4 3
"""
MTL = "newmtl grey\nKd 0.5 0.5 0.5\n"


@pytest.fixture
def plate(tmp_path: Path) -> Path:
    (tmp_path / "plate.mtl").write_text(MTL, encoding="utf-8")
    path = tmp_path / "plate.obj"
    path.write_text(OBJ, encoding="utf-8")
    return path


def _material_of(mesh, part: str):
    index = mesh.part_names.index(part)
    return mesh.materials[mesh.part_materials[index]]


def test_a_part_takes_the_library_material_for_the_scenario_band(plate: Path) -> None:
    config = TargetConfig(mesh={"path": plate, "materials": {"foil": "library:gold"}})
    for band in ((450.0, 900.0), (500.0, 650.0)):
        mesh = config.build(band)
        gold = _material_of(mesh, "foil")
        expected = material_from_entry("gold", band)
        assert gold.name == "library:gold"
        np.testing.assert_allclose(gold.base_color_rgb, expected.base_color_rgb, rtol=0, atol=0)
        assert (gold.metallic, gold.roughness, gold.ior) == (
            expected.metallic,
            expected.roughness,
            expected.ior,
        )
        # The other part keeps the file's values.
        assert _material_of(mesh, "panel").base_color_rgb == pytest.approx((0.5, 0.5, 0.5))
    # Gold is yellow over 450-900 nm (its blue third below 500 nm is dark); over 500-650 nm
    # its colour differs: the band decides.
    wide = _material_of(config.build((450.0, 900.0)), "foil").base_color_rgb
    narrow = _material_of(config.build((500.0, 650.0)), "foil").base_color_rgb
    assert wide[2] < wide[0]
    assert not np.allclose(wide, narrow, atol=1e-3)


def test_unknown_library_names_are_refused_with_the_choices() -> None:
    with pytest.raises(ValidationError) as error:
        TargetConfig(mesh={"path": "x.obj", "materials": {"foil": "library:unobtainium"}})
    message = str(error.value)
    assert "library:unobtainium" in message and "library:gold" in message


def test_procedural_satellites_take_the_library_materials_when_asked() -> None:
    from satsight.scene.band_reflectance import BUILTIN_LIBRARY_MATCH
    from satsight.scene.materials import FIRST_MATERIALS

    band = (450.0, 900.0)
    builtin = TargetConfig(
        procedural={"satellite_class": "two_wings", "seed": 2, "materials": "builtin"}
    ).build()
    library = TargetConfig(
        procedural={"satellite_class": "two_wings", "seed": 2, "materials": "library"}
    ).build(band)
    # Same geometry and part materials by name; the definitions differ where matched.
    np.testing.assert_array_equal(builtin.vertices_m, library.vertices_m)
    assert builtin.part_materials == library.part_materials
    for name in set(library.part_materials):
        got = library.materials[name]
        if name in BUILTIN_LIBRARY_MATCH:
            expected = material_from_entry(BUILTIN_LIBRARY_MATCH[name], band)
            assert got.base_color_rgb == expected.base_color_rgb and got.name == name
            assert got.roughness == expected.roughness
        else:
            assert got == FIRST_MATERIALS[name]
    # The solar-cell texture's colours follow the cell material.
    cells = library.part_names.index(next(n for n in library.part_names if n.endswith("_cells")))
    a = builtin.part_textures[cells].base_color.pixels
    b = library.part_textures[cells].base_color.pixels
    assert a.shape == b.shape and not np.array_equal(a, b)
