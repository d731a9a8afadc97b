"""CloudSat (NASA/JPL, 2006): BCP-2000 bus and the 94 GHz Cloud Profiling Radar.

Sources:

* Size 2.54 x 2.03 x 2.29 m (height x length x width), launch mass 700 kg, BCP-2000 bus by
  Ball Aerospace: NASA/JPL CloudSat, as given in the Wikipedia infobox "CloudSat".
* The Cloud Profiling Radar, a 94 GHz nadir-looking radar built by JPL: same article; its
  1.85 m reflector: JPL CloudSat instrument description (figure recalled, not re-read
  here: treat as estimated to a few per cent).
* 700 W of DC power: TBS satellite encyclopedia, "CloudSat".

Estimated: the split of the 2.54 m height into the bus and the radar, the radar's focal
length and feed, two wings of two 1.3 m x 1.1 m panels, antennas and radiators.

Body frame: origin at the centre of the bus box; +z nadir, the radar's boresight (the dish
on the +z deck looks along +z); x along the 2.03 m length, y along the 2.29 m width and
the wing axis. The seed turns the solar-array drive angle.
"""

from __future__ import annotations

import numpy as np

from satsight.scene.primitives import Parts, pose
from satsight.scene.replicas import parts as rp

ENVELOPE_M = (2.03, 2.29, 2.54)  # length (x), width (y), height (z) with the radar
DISH_DIAMETER_M = 1.85
DISH_FOCAL_M = 0.35 * DISH_DIAMETER_M
MOUNT_M = 0.1
WING_PANELS = 2
PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M = 1.3, 1.1, 0.4


def build(parts: Parts, rng: np.random.Generator) -> None:
    """Add CloudSat's parts (module docstring) to ``parts``; ``rng`` draws the drive."""
    lx, wy, hz = ENVELOPE_M
    horn_top = DISH_FOCAL_M + 0.04 * DISH_DIAMETER_M  # add_dish's horn: 0.08 D long
    bus_h = hz - MOUNT_M - horn_top
    bottom = -0.5 * bus_h
    rp.mli_box(parts, "bus_mli", rp.MLI_GOLD, (lx, wy - 0.04, bus_h - 0.01), (0, 0, 0.005))
    rp.plain_box(
        parts, "bus_crinkle", rp.BLACK_PAINT, (0.9 * lx, 0.9 * wy, 0.01), (0, 0, bottom + 0.005)
    )
    for k, sign in enumerate((1.0, -1.0), start=1):
        rp.radiator(
            parts,
            f"radiator_{k}",
            rp.WHITE_PAINT,
            (0.02, 0.7 * wy, 0.6 * bus_h),
            (sign * (0.5 * lx - 0.01), 0, 0.1),
        )
    top = 0.5 * bus_h
    rp.cylinder(parts, "radar_mount", rp.ALUMINIUM, (0, 0, top), (0, 0, top + MOUNT_M), 0.35, 48)
    rp.plain_box(
        parts, "radar_electronics", rp.MLI_SILVER, (0.5, 0.4, 0.3), (0.7, 0.75, top + 0.15)
    )
    rp.add_dish(
        parts,
        "radar_dish",
        DISH_DIAMETER_M,
        DISH_FOCAL_M,
        pose(None, (0, 0, top + MOUNT_M)),
        rp.WHITE_PAINT,
    )
    rp.cylinder(
        parts,
        "s_band_antenna",
        rp.WHITE_PAINT,
        (-0.6, 0.6, bottom),
        (-0.6, 0.6, bottom - 0.1),
        0.06,
    )
    rp.add_opposed_wings(
        parts, ("wing_1", "wing_2"), WING_PANELS, PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M,
        np.array([0.0, 0.5 * wy - 0.02, -0.2]), rng,
    )  # fmt: skip
