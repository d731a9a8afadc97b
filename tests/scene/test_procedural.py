"""Procedural satellites: determinism, size, parts per class, closed outward parts, frame."""

from __future__ import annotations

import re
from functools import cache

import numpy as np
import pytest

from mesh_parts import part
from satsight.errors import SatsightError
from satsight.scene.materials import FIRST_MATERIALS
from satsight.scene.mesh import TargetMesh
from satsight.scene.procedural import SATELLITE_CLASSES, generate_satellite

SEEDS = range(8)
MIN_TRIANGLE_AREA_M2 = 1e-8  # a 0.1 mm x 0.1 mm triangle; anything smaller is degenerate
WING_CELLS = {"body_mounted": 0, "one_wing": 1, "two_wings": 2, "four_panels": 4}
WING_CELLS["two_wings_dish"] = 2
BUS_PARTS = {
    "bus_mli": {"mli_gold", "mli_silver"},
    "instrument_deck": {"brushed_aluminium"},
    "radiator_1": {"white_paint"},
    "radiator_2": {"white_paint"},
    "bus_crinkle": {"black_crinkle"},
    "telescope_tube": {"cfrp"},
    "telescope_lens": {"optical_lens"},
    "antenna_dish": {"antenna_white"},
    "antenna_feed": {"black_metal"},
}


@cache
def satellite(satellite_class: str, seed: int) -> TargetMesh:
    return generate_satellite(satellite_class, seed)


def materials_of(mesh: TargetMesh) -> dict[str, str]:
    return dict(zip(mesh.part_names, mesh.part_materials, strict=True))


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_same_seed_gives_identical_arrays(satellite_class: str) -> None:
    a = generate_satellite(satellite_class, 11)
    b = generate_satellite(satellite_class, 11)
    np.testing.assert_array_equal(a.vertices_m, b.vertices_m)
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.face_part_index, b.face_part_index)
    assert (a.part_names, a.part_materials) == (b.part_names, b.part_materials)
    assert a.name == f"{satellite_class}-seed11"


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_different_seeds_give_different_satellites(satellite_class: str) -> None:
    a, b = satellite(satellite_class, 0), satellite(satellite_class, 1)
    assert not np.allclose(a.extent_m, b.extent_m)


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_largest_extent_is_between_2_and_10_m(satellite_class: str) -> None:
    for seed in SEEDS:
        assert 2.0 <= satellite(satellite_class, seed).extent_m.max() <= 10.0, seed


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_parts_have_unique_names_known_materials_and_moderate_size(satellite_class: str) -> None:
    for seed in SEEDS:
        mesh = satellite(satellite_class, seed)
        assert len(set(mesh.part_names)) == len(mesh.part_names)
        assert set(mesh.part_materials) <= set(FIRST_MATERIALS)
        assert 1_000 <= len(mesh.faces) <= 30_000
        counts = np.bincount(mesh.face_part_index, minlength=len(mesh.part_names))
        assert np.all(counts > 0)  # no empty part


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_every_class_has_the_icesat2_components(satellite_class: str) -> None:
    for seed in SEEDS:
        materials = materials_of(satellite(satellite_class, seed))
        for name, allowed in BUS_PARTS.items():
            assert materials[name] in allowed, (seed, name)
        if "telescope_baffle" in materials:
            assert materials["telescope_baffle"] == "black_crinkle"
        instruments = [n for n in materials if re.fullmatch(r"instrument_\d+", n)]
        assert instruments, seed
        assert {materials[n] for n in instruments} <= {
            "instrument_grey",
            "brushed_aluminium",
            "black_metal",
        }


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_solar_panel_count_per_class(satellite_class: str) -> None:
    for seed in SEEDS:
        materials = materials_of(satellite(satellite_class, seed))
        wings = sorted(int(m[1]) for n in materials if (m := re.fullmatch(r"wing_(\d+)_cells", n)))
        assert wings == list(range(1, WING_CELLS[satellite_class] + 1)), seed
        for k in wings:
            assert materials[f"wing_{k}_cells"] == "solar_cell"
            assert materials[f"wing_{k}_substrate"] == "panel_substrate"
            assert materials[f"wing_{k}_hinge"] == "titanium_hinge"
        body_cells = [n for n in materials if n.startswith("body_cells_")]
        cell_parts = [n for n, m in materials.items() if m == "solar_cell"]
        if satellite_class == "body_mounted":
            assert not any(n.startswith("wing_") for n in materials)
            assert len(body_cells) == 2 and sorted(cell_parts) == sorted(body_cells)
        else:
            assert not body_cells and len(cell_parts) == len(wings)


def test_dish_class_has_a_much_larger_dish() -> None:
    for seed in SEEDS:
        small = part(satellite("two_wings", seed), "antenna_dish").extents.max()
        large = part(satellite("two_wings_dish", seed), "antenna_dish").extents.max()
        assert small <= 0.8 < 2.0 <= large


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_parts_are_closed_outward_and_without_degenerate_triangles(satellite_class: str) -> None:
    for seed in range(3):
        mesh = satellite(satellite_class, seed)
        for name in mesh.part_names:
            piece = part(mesh, name)
            assert piece.is_watertight, (seed, name)
            assert piece.is_winding_consistent, (seed, name)
            assert piece.volume > 0, (seed, name)  # normals point outwards
            assert piece.area_faces.min() > MIN_TRIANGLE_AREA_M2, (seed, name)


@pytest.mark.parametrize("satellite_class", SATELLITE_CLASSES)
def test_body_frame_bus_centred_boresight_plus_z(satellite_class: str) -> None:
    for seed in SEEDS:
        mesh = satellite(satellite_class, seed)
        bus = part(mesh, "bus_mli")
        np.testing.assert_allclose(bus.bounds.mean(axis=0), 0.0, atol=1e-9)
        deck_top = part(mesh, "instrument_deck").bounds[1, 2]
        tube, lens = part(mesh, "telescope_tube"), part(mesh, "telescope_lens")
        assert tube.bounds[0, 2] == pytest.approx(deck_top, abs=1e-9)
        assert lens.bounds[0, 2] == pytest.approx(tube.bounds[1, 2], abs=1e-9)  # lens at +z end
        np.testing.assert_allclose(lens.centroid[:2], tube.centroid[:2], atol=1e-9)


@pytest.mark.parametrize("satellite_class", ["two_wings", "two_wings_dish"])
def test_two_wings_extend_along_plus_and_minus_y(satellite_class: str) -> None:
    for seed in SEEDS:
        mesh = satellite(satellite_class, seed)
        bus_half_y = part(mesh, "bus_mli").bounds[1, 1]
        assert part(mesh, "wing_1_cells").bounds[0, 1] > bus_half_y
        assert part(mesh, "wing_2_cells").bounds[1, 1] < -bus_half_y


def test_large_dish_looks_along_minus_x() -> None:
    for seed in SEEDS:
        mesh = satellite("two_wings_dish", seed)
        bus_min_x = part(mesh, "bus_mli").bounds[0, 0]
        dish = part(mesh, "antenna_dish")
        assert dish.bounds[1, 0] < bus_min_x
        feed_tip = part(mesh, "antenna_feed").bounds[0, 0]
        assert feed_tip < dish.bounds[0, 0] + 1e-9  # the focus lies beyond the concave side


def test_unknown_class_lists_the_valid_ones() -> None:
    with pytest.raises(SatsightError, match="unknown satellite class 'three_wings'") as error:
        generate_satellite("three_wings", 0)
    for name in SATELLITE_CLASSES:
        assert name in str(error.value)


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True])
def test_seed_must_be_a_non_negative_integer(seed) -> None:
    with pytest.raises(SatsightError, match="seed must be a non-negative integer"):
        generate_satellite("one_wing", seed)
