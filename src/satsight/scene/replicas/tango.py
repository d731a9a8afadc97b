"""Tango (PRISMA mission, SSC, 2010): the target spacecraft of SPEED and SPEED+.

Sources:

* Size 570 x 740 x 295 mm and mass 40 kg: D'Amico, Ardaens and Larsson, "Spaceborne
  autonomous formation-flying experiment on the PRISMA mission", J. Guid. Control Dyn.
  35(3), 2012, as given in the infobox of the German Wikipedia article "Prisma
  (schwedische Satelliten)"; 90 W: English Wikipedia "Prisma (satellite project)".
* Fixed solar panels; Tango about the size of a microwave oven, sun-pointing:
  Spaceflight Now, "Sweden's Prisma satellites go their separate ways" (Aug. 2010).
* Coarse 3-axis attitude control by magnetometers, sun sensors and magnetorquers; GPS and
  FFRF antennas: CNES, "PRISMA-FFIORD: satellites" (prisma-ffiord.cnes.fr).
* Tango as the pose-estimation target, its keypoints the body's corners and three
  antenna tips: Kisantal et al., "Satellite pose estimation challenge: dataset,
  competition design and results", IEEE TAES 56(5), 2020 (SPEED); Park et al., "SPEED+:
  next-generation dataset for spacecraft pose estimation across domain gap", IEEE
  Aerospace Conference 2022.

Estimated: the solar panel's 20 mm thickness, the three antennas' lengths (0.2-0.3 m)
and positions, the patch antennas and sun sensors.

Body frame: origin at the centre of the 570 x 740 x 295 mm box (solar panel included);
x along the 570 mm side, y along the 740 mm side, +z the solar panel's normal (the
sun-pointing face; Tango has no main instrument, so +z is also its "boresight"). The
antennas stand on the -z face. The panel is fixed: the seed changes nothing.
"""

from __future__ import annotations

import numpy as np

from satsight.scene.primitives import Parts, box, cell_surface
from satsight.scene.replicas import parts as rp

SIZE_M = (0.57, 0.74, 0.295)
PANEL_THICKNESS_M = 0.02
# (foot x, foot y, tip x, tip y, tip z) of each antenna, m; the foot is on the -z face
ANTENNAS_M = (
    (0.2, 0.3, 0.28, 0.42, -0.45),
    (-0.2, 0.3, -0.28, 0.42, -0.45),
    (0.0, -0.3, 0.0, -0.42, -0.35),
)


def build(parts: Parts, rng: np.random.Generator) -> None:
    """Add Tango's parts (module docstring) to ``parts``; ``rng`` is not used."""
    del rng
    sx, sy, sz = SIZE_M
    body_h = sz - PANEL_THICKNESS_M
    bottom = -0.5 * sz
    rp.mli_box(parts, "body", rp.MLI_SILVER, (sx, sy, body_h), (0, 0, bottom + 0.5 * body_h))
    panel_z = bottom + body_h
    substrate = box((sx, sy, 0.5 * PANEL_THICKNESS_M), (0, 0, panel_z + 0.25 * PANEL_THICKNESS_M))
    parts.add("solar_panel_substrate", rp.CFRP, substrate)
    area = (sy - 0.02, sx - 0.02)  # cells along y (u) and x (v)
    cells = box(
        (area[1], area[0], 0.5 * PANEL_THICKNESS_M), (0, 0, panel_z + 0.75 * PANEL_THICKNESS_M)
    )
    axes = {0: (1, 2), 1: (0, 2), 2: (1, 0)}  # the +z face: u along y, v along x
    origin = (-0.5 * area[1], -0.5 * area[0], 0.0)
    cells, surface = cell_surface(parts, cells, area, origin, axes=axes)
    parts.add("solar_cells", rp.CELLS_GAAS, cells, surface)
    for k, (fx, fy, tx, ty, tz) in enumerate(ANTENNAS_M, start=1):
        rp.cylinder(parts, f"antenna_{k}", rp.TITANIUM, (fx, fy, bottom), (tx, ty, tz), 0.004, 12)
        rp.cylinder(
            parts,
            f"antenna_{k}_base",
            rp.BLACK_PAINT,
            (fx, fy, bottom),
            (fx, fy, bottom - 0.02),
            0.015,
            16,
        )
    for k, (x, y) in enumerate(((0.15, -0.1), (-0.15, -0.1)), start=1):
        rp.plain_box(
            parts, f"gps_patch_{k}", rp.WHITE_PAINT, (0.08, 0.08, 0.01), (x, y, bottom - 0.005)
        )
    rp.plain_box(
        parts, "sun_sensor", rp.BLACK_PAINT, (0.04, 0.01, 0.04), (0.1, -0.5 * sy - 0.005, 0.0)
    )
