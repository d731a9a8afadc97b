"""Procedural satellites: five classes of 2-10 m spacecraft built from closed primitives.

The parts are those of the paper's IceSat-2 model: an MLI-wrapped bus, solar wings (a cell
side stacked on a substrate, held by a titanium yoke/hinge), a paraboloid antenna dish, a
telescope tube ending in an optical lens, white-paint radiators, black-crinkle coating and
small instrument boxes. Every part is a closed, outward-facing, watertight triangle mesh
(possibly several closed components) with a unique name and a ``FIRST_MATERIALS`` material.

Body frame of every generated satellite (metres):

* origin: the centre of the bus box;
* +z: the telescope boresight; the instrument deck is the bus face at +z, and the telescope,
  the small antenna dish and the instruments stand on it, looking along +z;
* +y: the solar-wing axis; one-wing satellites deploy their wing along +y, two-wing ones
  along +y and -y (the ``cross`` layout of ``four_panels`` adds wings along +x and -x);
* +x: completes the right-handed frame (x = y cross z); radiators cover the upper half of
  the +x and -x faces, and the large dish of ``two_wings_dish`` sits on a boom along -x,
  looking along -x.

Wings turn about their own axis by one solar-array drive angle shared by all wings.

Surfaces (``smooth_normals``, ``textures``; on by default in scenarios): curved parts (dish,
cylinders, tubes) get crease-angle shading normals (``satsight.scene.normals``, 30
degrees), so they shade round while box edges stay sharp; solar cells show their cell
grid, the MLI bus its crinkle and the radiators their strips
(``satsight.scene.procedural_textures``). The textures are drawn from their own generator,
``default_rng([seed, 1])``, so they never change the geometry a seed gives.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from satsight.errors import SatsightError
from satsight.scene import procedural_textures as pt
from satsight.scene.band_reflectance import BandMaterials
from satsight.scene.materials import FIRST_MATERIALS, Material
from satsight.scene.mesh import TargetMesh, merge_parts
from satsight.scene.normals import DEFAULT_CREASE_ANGLE_DEG
from satsight.scene.primitives import Parts as _Parts
from satsight.scene.primitives import box as _box
from satsight.scene.primitives import cell_surface as _cell_surface
from satsight.scene.primitives import dish as _dish
from satsight.scene.primitives import join as _join
from satsight.scene.primitives import pose as _pose
from satsight.scene.primitives import rod as _rod
from satsight.scene.primitives import rot as _rot
from satsight.scene.primitives import textured as _textured
from satsight.scene.primitives import tube as _tube
from satsight.scene.replicas import REPLICA_CLASSES, build_replica
from satsight.scene.satellite_classes import SATELLITE_CLASSES

MAX_EXTENT_M = 9.8  # largest bounding-box side allowed before a safety rescale
MIN_EXTENT_M = 2.2

_INSTRUMENT_MATERIALS = ("instrument_grey", "brushed_aluminium", "black_metal")
_CELL_THICKNESS_M = 0.008
_SUBSTRATE_THICKNESS_M = 0.02
_DECK_THICKNESS_M = 0.02


# --- components ------------------------------------------------------------------------------
def _add_bus(parts: _Parts, rng: np.random.Generator, size_m: np.ndarray) -> None:
    """MLI bus box, aluminium deck at +z, radiators on +/-x, black crinkle at -z."""
    bx, by, bz = size_m
    bus = _box(size_m, (0, 0, 0))
    surface = None
    if parts.texture_rng is not None:
        crinkle = pt.mli_crinkle_textures(parts.texture_rng)
        tile = (pt.MLI_TILE_M, pt.MLI_TILE_M)
        bus, surface = _textured(bus, crinkle, tile, -0.5 * np.asarray(size_m))
    parts.add("bus_mli", str(rng.choice(["mli_gold", "mli_silver"])), bus, surface)
    deck = _box((bx, by, _DECK_THICKNESS_M), (0, 0, 0.5 * bz + 0.5 * _DECK_THICKNESS_M))
    parts.add("instrument_deck", "brushed_aluminium", deck)
    rad_z = (0.05 * bz, 0.45 * bz)
    for k, sign in enumerate((1.0, -1.0), start=1):
        centre = (sign * (0.5 * bx + 0.0075), 0.0, 0.5 * sum(rad_z))
        panel = _box((0.015, 0.8 * by, rad_z[1] - rad_z[0]), centre)
        surface = None
        if parts.texture_rng is not None:
            period = (pt.RADIATOR_STRIP_PERIOD_M, pt.RADIATOR_STRIP_PERIOD_M)
            origin = (0.0, -0.4 * by, rad_z[0])
            panel, surface = _textured(panel, pt.radiator_textures(parts.materials), period, origin)
        parts.add(f"radiator_{k}", "white_paint", panel, surface)
    crinkle = _box((0.9 * bx, 0.9 * by, 0.01), (0, 0, -0.5 * bz - 0.005))
    parts.add("bus_crinkle", "black_crinkle", crinkle)


def _place(rng, deck_half_m, radius_m, taken, inside: bool, tries: int = 60):
    """A footprint centre (x, y) on the deck whose circle misses the ``taken`` circles.

    ``inside``: the circle must also stay on the deck (else only its centre must).
    """
    margin = radius_m + 0.02 if inside else 0.0
    room = np.asarray(deck_half_m) - margin
    if np.any(room <= 0):
        return None
    for _ in range(tries):
        xy = rng.uniform(-room, room)
        if all(np.hypot(*(xy - c)) > radius_m + r + 0.03 for c, r in taken):
            return xy
    return None


def _add_deck_payload(
    parts: _Parts, rng: np.random.Generator, size_m: np.ndarray, small_dish: bool
) -> None:
    """Telescope (tube, optional baffle, lens), small dish on a mast, instrument boxes."""
    bx, by, bz = size_m
    half = np.array([0.5 * bx, 0.5 * by])
    top = 0.5 * bz + _DECK_THICKNESS_M
    taken: list[tuple[np.ndarray, float]] = []

    r_t = min(rng.uniform(0.12, 0.3), 0.3 * min(bx, by))
    length = rng.uniform(0.5, 1.3)
    xy = _place(rng, half, r_t, taken, inside=True)
    xy = np.zeros(2) if xy is None else xy
    taken.append((xy, r_t))
    end = top + length
    parts.add("telescope_tube", "cfrp", _rod((*xy, top), (*xy, end), r_t, sections=48))
    if rng.random() < 0.7:
        baffle = _tube(r_t - 0.005, r_t + 0.02, end - 0.05, end + rng.uniform(0.3, 0.8) * r_t, xy)
        parts.add("telescope_baffle", "black_crinkle", baffle)
    lens = _rod((*xy, end), (*xy, end + 0.01), 0.9 * r_t, sections=48)
    parts.add("telescope_lens", "optical_lens", lens)

    if small_dish:
        diameter = rng.uniform(0.3, 0.8)
        xy_d = _place(rng, half, 0.5 * diameter, taken, inside=False)
        while xy_d is None and diameter > 0.2:  # crowded deck: shrink the dish
            diameter *= 0.85
            xy_d = _place(rng, half, 0.5 * diameter, taken, inside=False)
        if xy_d is None:  # the deck corner opposite the telescope
            xy_d = np.where(xy > 0, -half, half)
        taken.append((xy_d, 0.5 * diameter))
        mast_top = top + rng.uniform(0.15, 0.4)
        _add_dish(parts, rng, diameter, _pose(None, (*xy_d, mast_top)), 0.012, 48)
        mast = _rod((*xy_d, top), (*xy_d, mast_top - 0.006), 0.025)
        parts.add("antenna_mast", "brushed_aluminium", mast)

    count = int(rng.integers(2, 6))
    placed = 0
    for _ in range(count):
        sx, sy = rng.uniform(0.12, 0.4, size=2)
        sz = rng.uniform(0.08, 0.35)
        radius = 0.5 * float(np.hypot(sx, sy))
        yaw = rng.uniform(0.0, np.pi)
        material = str(rng.choice(_INSTRUMENT_MATERIALS))
        xy_i = _place(rng, half, radius, taken, inside=True)
        if xy_i is None:
            continue
        taken.append((xy_i, radius))
        placed += 1
        box = _box((sx, sy, sz), (*xy_i, top + 0.5 * sz), _rot("z", yaw))
        parts.add(f"instrument_{placed}", material, box)


def _add_dish(
    parts: _Parts,
    rng: np.random.Generator,
    diameter_m: float,
    vertex_pose: np.ndarray,
    thickness_m: float,
    sections: int,
) -> None:
    """Dish (vertex at the pose origin, looking along the pose's +z) and its feed on the axis."""
    focal = rng.uniform(0.3, 0.45) * diameter_m
    dish = _dish(diameter_m, focal, thickness_m, sections)
    horn_r, horn_len = 0.04 * diameter_m, 0.06 * diameter_m
    strut = _rod(
        (0, 0, -0.5 * thickness_m), (0, 0, focal - 0.5 * horn_len), 0.004 + 0.006 * diameter_m
    )
    horn = _rod((0, 0, focal - 0.5 * horn_len), (0, 0, focal + 0.5 * horn_len), horn_r)
    feed = _join(strut, horn)
    dish.apply_transform(vertex_pose)
    feed.apply_transform(vertex_pose)
    parts.add("antenna_dish", "antenna_white", dish)
    parts.add("antenna_feed", "black_metal", feed)


def _wing_panel(
    parts: _Parts, index: int, root_m: float, length_m: float, width_m: float, pose: np.ndarray
) -> None:
    """Cells + substrate of one panel in a wing frame (y' outboard, cells facing +x')."""
    y_mid = root_m + 0.5 * length_m
    substrate = _box(
        (_SUBSTRATE_THICKNESS_M, length_m, width_m), (-0.5 * _SUBSTRATE_THICKNESS_M, y_mid, 0)
    )
    cells = _box(
        (_CELL_THICKNESS_M, length_m - 0.04, width_m - 0.04), (0.5 * _CELL_THICKNESS_M, y_mid, 0)
    )
    area = (length_m - 0.04, width_m - 0.04)  # cell area along y' (u) and z' (v)
    origin = (0.0, root_m + 0.02, -0.5 * area[1])
    cells, surface = _cell_surface(parts, cells, area, origin, pose=pose)
    parts.add(f"wing_{index}_cells", "solar_cell", cells, surface)
    parts.add(f"wing_{index}_substrate", "panel_substrate", substrate.apply_transform(pose))


def _add_wing(
    parts: _Parts,
    first_index: int,
    panels: int,
    direction: np.ndarray,
    face_offset_m: float,
    geometry: dict[str, float],
) -> None:
    """A deployable wing of ``panels`` panels in series, rooted on the bus face at z = 0.

    ``direction``: rotation (3, 3) taking the wing frame's +y' to the outboard body axis.
    The first panel hangs on a yoke (rod + hinge bar); later panels on a hinge bar.
    """
    gap, length, width = geometry["gap_m"], geometry["length_m"], geometry["width_m"]
    pose = _pose(direction @ _rot("y", geometry["drive_rad"]), direction @ [0, face_offset_m, 0])
    root = gap
    for k in range(panels):
        if k == 0:
            arm = _rod((0, 0, 0), (0, gap - 0.04, 0), 0.03)
            hinge = _join(
                arm, _rod((0, gap - 0.03, -0.4 * width), (0, gap - 0.03, 0.4 * width), 0.02)
            )
        else:
            y_h = root - 0.03
            hinge = _rod((0, y_h, -0.4 * width), (0, y_h, 0.4 * width), 0.015)
        parts.add(f"wing_{first_index + k}_hinge", "titanium_hinge", hinge.apply_transform(pose))
        _wing_panel(parts, first_index + k, root, length, width, pose)
        root += length + 0.06


_TO_PLUS_Y = np.eye(3)
_TO_MINUS_Y = _rot("z", np.pi)
_TO_PLUS_X = _rot("z", -0.5 * np.pi)
_TO_MINUS_X = _rot("z", 0.5 * np.pi)


def _add_wings(parts: _Parts, rng: np.random.Generator, cls: str, size_m: np.ndarray) -> float:
    """Deployable wings per class; returns the panel width (m) for clearance of the dish."""
    bx, by, bz = size_m
    gap = rng.uniform(0.3, 0.6)
    width = min(rng.uniform(0.6, 0.95) * bz, 2.0)
    drive = rng.uniform(-np.pi, np.pi)
    if cls == "one_wing":
        layout, panels, lengths = [(_TO_PLUS_Y, 0.5 * by)], 1, (2.0, 5.0, 9.0 - by - gap)
    elif cls in ("two_wings", "two_wings_dish"):
        layout, panels = [(_TO_PLUS_Y, 0.5 * by), (_TO_MINUS_Y, 0.5 * by)], 1
        lengths = (1.5, 3.8, 0.5 * (9.4 - by) - gap)
    elif str(rng.choice(["cross", "tandem"])) == "cross":
        layout = [
            (_TO_PLUS_Y, 0.5 * by),
            (_TO_MINUS_Y, 0.5 * by),
            (_TO_PLUS_X, 0.5 * bx),
            (_TO_MINUS_X, 0.5 * bx),
        ]
        panels, lengths = 1, (1.2, 3.0, 0.5 * (9.4 - max(bx, by)) - gap)
    else:  # tandem: two panels in series on each side
        layout, panels = [(_TO_PLUS_Y, 0.5 * by), (_TO_MINUS_Y, 0.5 * by)], 2
        lengths = (1.0, 2.0, 0.5 * (0.5 * (9.4 - by) - gap - 0.06))
    # lengths: (shortest, longest, longest that keeps the span under 9.4 m) of one panel
    length = rng.uniform(min(lengths[0], lengths[2]), min(lengths[1:]))
    geometry = {"gap_m": gap, "length_m": length, "width_m": width, "drive_rad": drive}
    for k, (direction, offset) in enumerate(layout):
        _add_wing(parts, 1 + k * panels, panels, direction, offset, geometry)
    return width


def _add_body_cells(parts: _Parts, size_m: np.ndarray) -> None:
    """Body-mounted solar cells covering most of the +y and -y bus faces."""
    bx, by, bz = size_m
    for k, sign in enumerate((1.0, -1.0), start=1):
        cells = _box((0.9 * bx, 0.01, 0.85 * bz), (0, sign * (0.5 * by + 0.005), 0))
        area = (0.9 * bx, 0.85 * bz)  # along x (u) and z (v)
        origin = (-0.45 * bx, 0.0, -0.425 * bz)
        cells, surface = _cell_surface(parts, cells, area, origin)
        parts.add(f"body_cells_{k}", "solar_cell", cells, surface)


def generate_satellite(
    satellite_class: str,
    seed: int,
    smooth_normals: bool = False,
    textures: bool = False,
    materials: Mapping[str, Material] | None = None,
) -> TargetMesh:
    """A random satellite of ``satellite_class`` (one of ``SATELLITE_CLASSES``), from ``seed``.

    The same (class, seed) always gives the same mesh (``np.random.default_rng(seed)``). The
    largest side of the bounding box lies in [2, 10] m. The mesh is in the body frame of the
    module docstring; parts are named ``bus_mli``, ``wing_<k>_cells``, ``antenna_dish``, ...
    smooth_normals: crease-angle shading normals on curved parts (else flat triangles).
    textures: cell grids, MLI crinkle and radiator strips (same geometry either way). Both
    are off here, so that the bare call keeps giving the flat, untextured mesh; scenarios
    switch them on by default (``target.procedural.smooth_normals`` / ``textures``).
    materials: the definitions of the built-in material names the parts use (default
    ``FIRST_MATERIALS``; ``band_reflectance.builtins_from_library`` gives them from the
    spectral library for a band). The textures' colours follow them.

    The replicas of real spacecraft (``REPLICA_CLASSES``, ``satsight.scene.replicas``) are
    built here too, at their real size (no rescale): their parts take library materials
    (``library:NAME``), so ``materials`` must then hold them (a
    ``band_reflectance.BandMaterials``, as ``builtins_from_library`` gives); None takes
    them for the default band, 450-900 nm.
    """
    if satellite_class not in SATELLITE_CLASSES + REPLICA_CLASSES:
        raise SatsightError(
            f"unknown satellite class '{satellite_class}'; expected one of: "
            f"{', '.join(SATELLITE_CLASSES)} or a replica: {', '.join(REPLICA_CLASSES)}"
        )
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SatsightError(f"seed must be a non-negative integer, got {seed!r}")
    if satellite_class in REPLICA_CLASSES:
        if materials is not None and "library:gold" not in materials:
            raise SatsightError(
                f"the replica '{satellite_class}' takes spectral-library materials; pass "
                "band_reflectance.BandMaterials(band_nm) (or None for 450-900 nm)"
            )
        return build_replica(
            satellite_class,
            int(seed),
            BandMaterials() if materials is None else materials,
            smooth_normals,
            textures,
        )
    rng = np.random.default_rng(int(seed))
    library = FIRST_MATERIALS if materials is None else materials
    missing = sorted(set(FIRST_MATERIALS) - set(library))
    if missing:
        raise SatsightError(f"materials must define every built-in name; missing {missing}")
    parts = _Parts(np.random.default_rng([int(seed), 1]) if textures else None, library)
    if satellite_class == "body_mounted":
        size = np.array([rng.uniform(1.4, 2.6), rng.uniform(1.4, 2.6), rng.uniform(1.8, 3.0)])
    else:
        size = np.array([rng.uniform(1.0, 2.0), rng.uniform(1.0, 2.0), rng.uniform(1.2, 2.4)])
    _add_bus(parts, rng, size)
    _add_deck_payload(parts, rng, size, small_dish=satellite_class != "two_wings_dish")
    if satellite_class == "body_mounted":
        _add_body_cells(parts, size)
    else:
        width = _add_wings(parts, rng, satellite_class, size)
        if satellite_class == "two_wings_dish":
            boom = 0.5 * width + rng.uniform(0.2, 0.5)
            vertex = (-(0.5 * size[0] + boom), 0.0, 0.0)
            parts.add("antenna_boom", "cfrp", _rod((-0.5 * size[0], 0, 0), vertex, 0.05))
            look_minus_x = _rot("y", -0.5 * np.pi)
            _add_dish(parts, rng, rng.uniform(2.0, 3.5), _pose(look_minus_x, vertex), 0.03, 72)
    items = _rescaled(parts.items)
    return merge_parts(
        items,
        materials={name: library[name] for name in FIRST_MATERIALS},
        name=f"{satellite_class}-seed{seed}",
        crease_angle_deg=DEFAULT_CREASE_ANGLE_DEG if smooth_normals else None,
    )


def _rescaled(items):
    """Safety net: scale uniformly about the origin if the largest extent leaves [2.2, 9.8] m."""
    vertices = np.concatenate([item[2] for item in items])
    largest = float((vertices.max(axis=0) - vertices.min(axis=0)).max())
    scale = float(np.clip(largest, MIN_EXTENT_M, MAX_EXTENT_M)) / largest
    if scale == 1.0:
        return items
    return [(n, m, v * scale, f, *rest) for n, m, v, f, *rest in items]
