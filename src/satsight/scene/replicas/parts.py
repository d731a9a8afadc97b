"""Components shared by the replicas: MLI boxes, solar wings, dishes, rods, radiators.

Every component is a closed, outward-facing solid (``satsight.scene.primitives``) and takes
a material of the spectral library by its scenario name ``library:NAME`` (the constants
below). Lengths in metres, in the replica's body frame.
"""

from __future__ import annotations

import numpy as np
import trimesh

from satsight.scene import procedural_textures as pt
from satsight.scene.primitives import (
    Parts,
    box,
    cell_surface,
    dish,
    join,
    pose,
    rod,
    rot,
    textured,
)

# Library materials (``satsight materials``) the replicas use.
MLI_GOLD = "library:mli_aluminised_kapton"  # amber outer layer of MLI blankets
MLI_SILVER = "library:aluminium_teflon"  # silvered FEP outer layer
MLI_BLACK = "library:black_kapton"
BETA_CLOTH = "library:beta_cloth"
CELLS_GAAS = "library:gaas_solar_cell"
CELLS_SI = "library:si_solar_cell"
OSR = "library:radiator_osr_ceria_glass"
WHITE_PAINT = "library:white_paint_az93"
BLACK_PAINT = "library:black_paint_z306"
CFRP = "library:cfrp"
ALUMINIUM = "library:aluminium"
ANODISED = "library:anodised_aluminium"
TITANIUM = "library:titanium"
GOLD = "library:gold"
SILVER_TEFLON = "library:silver_teflon"

CELL_THICKNESS_M = 0.008
SUBSTRATE_THICKNESS_M = 0.02

TO_PLUS_Y = np.eye(3)
TO_MINUS_Y = rot("z", np.pi)


def mli_box(parts: Parts, name: str, material: str, extents_m, centre_m) -> None:
    """A box wrapped in MLI (crinkle normal map when textures are on)."""
    mesh = box(extents_m, centre_m)
    surface = None
    if parts.texture_rng is not None:
        crinkle = pt.mli_crinkle_textures(parts.texture_rng)
        origin = np.asarray(centre_m, dtype=float) - 0.5 * np.asarray(extents_m, dtype=float)
        mesh, surface = textured(mesh, crinkle, (pt.MLI_TILE_M, pt.MLI_TILE_M), origin)
    parts.add(name, material, mesh, surface)


def plain_box(parts: Parts, name: str, material: str, extents_m, centre_m, rotation=None) -> None:
    parts.add(name, material, box(extents_m, centre_m, rotation))


def radiator(parts: Parts, name: str, material: str, extents_m, centre_m) -> None:
    """A radiator plate; white-paint ones show their tape strips when textures are on."""
    mesh = box(extents_m, centre_m)
    surface = None
    if parts.texture_rng is not None and material == WHITE_PAINT:
        period = (pt.RADIATOR_STRIP_PERIOD_M, pt.RADIATOR_STRIP_PERIOD_M)
        origin = np.asarray(centre_m, dtype=float) - 0.5 * np.asarray(extents_m, dtype=float)
        mesh, surface = textured(mesh, pt.radiator_textures(parts.materials), period, origin)
    parts.add(name, material, mesh, surface)


def cylinder(
    parts: Parts, name: str, material: str, start_m, end_m, radius_m: float, sections: int = 32
) -> None:
    parts.add(name, material, rod(start_m, end_m, radius_m, sections))


def hexagonal_prism(across_corners_m: float, z0_m: float, z1_m: float) -> trimesh.Trimesh:
    """Closed hexagonal prism about the z axis (corners on +/-x), from z0 to z1."""
    return rod((0, 0, z0_m), (0, 0, z1_m), 0.5 * across_corners_m, sections=6)


def add_dish(
    parts: Parts,
    name: str,
    diameter_m: float,
    focal_m: float,
    vertex_pose: np.ndarray,
    material: str = WHITE_PAINT,
    feed: bool = True,
    thickness_m: float = 0.03,
) -> None:
    """Paraboloid reflector (vertex at the pose origin, looking along the pose's +z) and,
    with ``feed``, a feed horn on a strut at the focus (part ``<name>_feed``)."""
    reflector = dish(diameter_m, focal_m, thickness_m, 72)
    parts.add(name, material, reflector.apply_transform(vertex_pose))
    if feed:
        horn_r, horn_len = 0.04 * diameter_m, 0.08 * diameter_m
        strut = rod((0, 0, -0.5 * thickness_m), (0, 0, focal_m - 0.5 * horn_len), 0.015)
        horn = rod((0, 0, focal_m - 0.5 * horn_len), (0, 0, focal_m + 0.5 * horn_len), horn_r)
        parts.add(f"{name}_feed", BLACK_PAINT, join(strut, horn).apply_transform(vertex_pose))


def add_wing(
    parts: Parts,
    prefix: str,
    panels: int,
    panel_length_m: float,
    panel_width_m: float,
    yoke_m: float,
    direction: np.ndarray,
    root_offset_m,
    drive_rad: float,
    cells: str = CELLS_GAAS,
    panel_gap_m: float = 0.05,
) -> None:
    """A solar wing: a yoke of ``yoke_m`` from the root, then ``panels`` panels in series.

    In the wing frame the wing runs along +y' from the root, the panels span z' (width)
    and the cells face +x'; ``direction`` (3, 3) turns +y' to the outboard body axis and
    ``drive_rad`` turns the wing about its axis (the solar-array drive). ``root_offset_m``
    (3,) is the root in the body frame. Parts: ``<prefix>_yoke`` (titanium), then per
    panel ``<prefix>_panel_<k>_cells`` and ``<prefix>_panel_<k>_substrate`` (CFRP).
    """
    wing_pose = pose(direction @ rot("y", drive_rad), root_offset_m)
    arm = rod((0, 0, 0), (0, yoke_m - 0.03, 0), 0.03)
    bar = rod(
        (0, yoke_m - 0.03, -0.4 * panel_width_m), (0, yoke_m - 0.03, 0.4 * panel_width_m), 0.02
    )
    parts.add(f"{prefix}_yoke", TITANIUM, join(arm, bar).apply_transform(wing_pose))
    root = yoke_m
    for k in range(1, panels + 1):
        y_mid = root + 0.5 * panel_length_m
        substrate = box(
            (SUBSTRATE_THICKNESS_M, panel_length_m, panel_width_m),
            (-0.5 * SUBSTRATE_THICKNESS_M, y_mid, 0),
        )
        area = (panel_length_m - 0.04, panel_width_m - 0.04)
        cell_box = box((CELL_THICKNESS_M, *area), (0.5 * CELL_THICKNESS_M, y_mid, 0))
        origin = (0.0, root + 0.02, -0.5 * area[1])
        cell_mesh, surface = cell_surface(parts, cell_box, area, origin, pose=wing_pose)
        parts.add(f"{prefix}_panel_{k}_cells", cells, cell_mesh, surface)
        parts.add(f"{prefix}_panel_{k}_substrate", CFRP, substrate.apply_transform(wing_pose))
        root += panel_length_m + panel_gap_m


def wing_span_from_root_m(panels: int, panel_length_m: float, yoke_m: float, gap_m=0.05):
    """Distance from a wing's root to its tip along the wing axis, m."""
    return yoke_m + panels * panel_length_m + (panels - 1) * gap_m


def add_opposed_wings(
    parts: Parts,
    names: tuple[str, str],
    panels: int,
    panel_length_m: float,
    panel_width_m: float,
    yoke_m: float,
    root_m,
    rng: np.random.Generator,
) -> None:
    """Two wings (``add_wing``) deployed along +y and -y, turned by one solar-array drive
    angle uniform in +-60 deg (one draw from ``rng``). ``root_m`` (3,): the root of the +y
    wing in its own frame's axes (x, outboard y, z); the -y wing's is its mirror."""
    drive = rng.uniform(-np.pi / 3, np.pi / 3)
    for name, direction in zip(names, (TO_PLUS_Y, TO_MINUS_Y), strict=True):
        root = direction @ np.asarray(root_m, dtype=np.float64)
        add_wing(parts, name, panels, panel_length_m, panel_width_m, yoke_m, direction, root, drive)
