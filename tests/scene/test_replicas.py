"""Replicas of real spacecraft: published dimensions, closed outward parts, library
materials, rendering and export."""

from __future__ import annotations

import json
import re
from functools import cache

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from mesh_parts import part
from satsight.errors import SatsightError
from satsight.scene.material_library import LIBRARY_PREFIX, list_materials
from satsight.scene.mesh import TargetMesh
from satsight.scene.procedural import generate_satellite
from satsight.scene.replicas import REPLICA_CLASSES

MIN_TRIANGLE_AREA_M2 = 1e-8
# Published sizes are given to 2-3 significant figures and the replicas add skins (MLI,
# radiators 20 mm) on the bus: 2 % covers both.
SIZE_REL = 0.02
# Solar constant 1361 W m^-2 (Kopp & Lean 2011, GRL 38 L01706) times a triple-junction
# GaAs cell efficiency of 28 % (Spectrolab UTJ data sheet, beginning of life).
CELL_W_PER_M2 = 1361.0 * 0.28


@cache
def replica(name: str, seed: int = 0) -> TargetMesh:
    return generate_satellite(name, seed)


def extent_of(mesh: TargetMesh, pattern: str) -> np.ndarray:
    """Bounding-box sides (3,) of the parts whose names match ``pattern``, m."""
    chosen = [i for i, n in enumerate(mesh.part_names) if re.fullmatch(pattern, n)]
    assert chosen, pattern
    v = mesh.vertices_m[np.unique(mesh.faces[np.isin(mesh.face_part_index, chosen)])]
    return v.max(axis=0) - v.min(axis=0)


def diameter_of(mesh: TargetMesh, name: str) -> float:
    """Largest distance between two vertices of a part (a dish's rim diameter), m."""
    hull = part(mesh, name).convex_hull
    return float(pdist(hull.vertices).max())


def cell_area_m2(mesh: TargetMesh) -> float:
    """Sunward cell area: half the surface of the thin cell slabs, minus their edges."""
    total = 0.0
    for name in mesh.part_names:
        if name.endswith("cells"):
            slab = part(mesh, name)
            sides = np.sort(slab.bounding_box_oriented.primitive.extents)
            total += sides[1] * sides[2]
    return total


# (parts pattern, published extents (x, y, z) m, source)
ENVELOPES = {
    "icesat2": (r"bus_mli|atlas_mli|atlas_radiator_\d|telescope_.*", (1.9, 2.5, 3.8),
                "NASA ICESat-2 press kit: 2.5 x 1.9 x 3.8 m at launch"),
    "cloudsat": (r"bus_.*|radiator_\d|radar_.*", (2.03, 2.29, 2.54),
                 "NASA/JPL: 2.54 x 2.03 x 2.29 m (H x L x W)"),
    "tango": (r"body|solar_.*", (0.57, 0.74, 0.295), "D'Amico et al. 2012: 570 x 740 x 295 mm"),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(ENVELOPES))
def test_envelope_matches_the_published_size(name: str) -> None:
    pattern, published, _source = ENVELOPES[name]
    np.testing.assert_allclose(extent_of(replica(name), pattern), published, rtol=SIZE_REL)


def test_oco2_hexagonal_bus_matches_its_stowed_size() -> None:
    # Orbital Sciences fact sheet: stowed 2.12 m x 0.94 m (the hexagon's corner diameter).
    mesh = replica("oco2")
    extent = extent_of(mesh, r"bus_mli|instrument_mli|launch_adapter_ring")
    assert extent[2] == pytest.approx(2.12, rel=SIZE_REL)
    assert extent[0] == pytest.approx(0.94, rel=SIZE_REL)
    assert extent[1] == pytest.approx(0.94 * np.cos(np.pi / 6), rel=SIZE_REL)  # flat to flat


def test_dishes_and_telescope_have_their_published_diameters() -> None:
    # ATLAS telescope 2.6 ft (NASA GSFC 2014); CPR reflector 1.85 m (JPL); the Poseidon-3
    # dish of Jason-2 taken as Jason-1's Poseidon-2, 1.2 m.
    telescope = extent_of(replica("icesat2"), r"telescope_barrel")
    assert telescope[0] == pytest.approx(2.6 * 0.3048, rel=SIZE_REL)
    assert diameter_of(replica("cloudsat"), "radar_dish") == pytest.approx(1.85, rel=SIZE_REL)
    assert diameter_of(replica("jason2"), "altimeter_dish") == pytest.approx(1.2, rel=SIZE_REL)


def test_galaxy19_wings_span_25_to_30_m_and_dwarf_tango() -> None:
    # SS/L 1300 class: wings 25-30 m tip to tip; Tango < 1 m: real sizes, no rescale.
    span = extent_of(replica("galaxy19"), r"wing_.*|bus_mli")[1]
    assert 25.0 <= span <= 30.0
    assert replica("tango").extent_m.max() < 1.0


@pytest.mark.parametrize(
    ("name", "published_w"),
    [("icesat2", 3818.0), ("oco2", 815.0), ("cloudsat", 700.0), ("jason2", 511.0), ("tango", 90.0)],
)
def test_cell_area_can_supply_the_published_power(name: str, published_w: float) -> None:
    # Powers: Orbital ATK (ICESat-2 array, end of life), Orbital Sciences (OCO-2), TBS
    # (CloudSat), CNES (Jason-2), Wikipedia PRISMA (Tango). The cells facing the Sun at
    # 28 % must give at least that and, allowing for orbit average, degradation and
    # margins, not more than 4 times it.
    supply_w = cell_area_m2(replica(name)) * CELL_W_PER_M2
    assert published_w <= supply_w <= 4.0 * published_w


@pytest.mark.parametrize("name", REPLICA_CLASSES)
def test_parts_closed_outward_unique_with_library_materials(name: str) -> None:
    mesh = replica(name)
    assert len(set(mesh.part_names)) == len(mesh.part_names)
    library = {LIBRARY_PREFIX + m for m in list_materials()}
    assert set(mesh.part_materials) <= library
    assert set(mesh.materials) == set(mesh.part_materials)
    for part_name in mesh.part_names:
        piece = part(mesh, part_name)
        assert piece.is_watertight, part_name
        assert piece.is_winding_consistent, part_name
        assert piece.volume > 0, part_name
        assert piece.area_faces.min() > MIN_TRIANGLE_AREA_M2, part_name


def test_seed_turns_only_the_solar_array_drive() -> None:
    a, b = replica("jason2", 0), replica("jason2", 1)
    assert a.part_names == b.part_names
    for name in a.part_names:
        if not name.startswith("wing_"):
            np.testing.assert_array_equal(part(a, name).vertices, part(b, name).vertices, name)
    tip = "wing_1_panel_4_cells"
    assert not np.allclose(part(a, tip).vertices, part(b, tip).vertices)
    np.testing.assert_array_equal(replica("tango", 0).vertices_m, replica("tango", 5).vertices_m)


@pytest.mark.parametrize("name", REPLICA_CLASSES)
def test_replica_renders_and_exports_a_valid_dataset(name: str, tmp_path) -> None:
    from satsight.config.scenario import parse_scenario
    from satsight.dataset.image_files import read_png
    from satsight.dataset.validate import validate_dataset
    from satsight.run.generation import generate_dataset

    size_m = float(replica(name).extent_m.max())  # wide_field: 96 px span 2.1 mrad
    scenario = {
        "name": f"replica-{name}",
        "seed": 3,
        "camera": {"preset": "wide_field", "width_px": 128, "height_px": 96},
        "target": {"procedural": {"satellite_class": name, "seed": 0}},
        "frames": [
            {"distance_km": 0.8 * size_m, "azimuth_deg": 35, "elevation_deg": 25, "roll_deg": 0}
        ],
        "render": {"bounces": 1},
    }
    out = tmp_path / "dataset"
    summary = generate_dataset(parse_scenario(scenario), out)
    assert summary.complete and summary.rendered == 1
    report = validate_dataset(out)
    assert report.ok, [str(p) for p in report.findings.problems]
    labels = json.loads((out / "labels.json").read_text(encoding="utf-8"))
    frame = labels["frames"][0]
    ids = np.unique(read_png(out / frame["files"]["part_mask_png16"]))
    parts_by_id = {p["part_id"]: p["name"] for p in labels["target"]["parts"]}
    seen = {parts_by_id[int(i)] for i in ids if i > 0}
    assert len(seen) >= 3  # the bus and more than one other part are in view
    assert any(n.startswith(("bus", "body")) for n in seen), seen


def test_builtin_material_mapping_is_refused_for_replicas() -> None:
    from satsight.scene.materials import FIRST_MATERIALS

    with pytest.raises(SatsightError, match="takes spectral-library materials"):
        generate_satellite("tango", 0, materials=FIRST_MATERIALS)


def test_scenario_refuses_builtin_materials_for_a_replica_and_defaults_to_library() -> None:
    from satsight.config.target import ProceduralTargetConfig

    assert ProceduralTargetConfig(satellite_class="galaxy19").materials == "library"
    with pytest.raises(ValueError, match="has spectral-library materials only"):
        ProceduralTargetConfig(satellite_class="galaxy19", materials="builtin")


def test_the_class_names_name_every_replica_builder() -> None:
    """satellite_classes.REPLICA_CLASSES (read by the scenario check without the builders)
    names the builders, in order."""
    from satsight.scene.replicas import _BUILDERS

    assert tuple(_BUILDERS) == REPLICA_CLASSES
