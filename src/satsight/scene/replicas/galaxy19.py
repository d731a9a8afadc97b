"""Galaxy 19 (Intelsat, 2008): an SS/L 1300 geostationary communications satellite.

Sources:

* Launch mass 4690 kg, SS/L 1300 platform built by Space Systems/Loral, 52 C- and Ku-band
  transponders, launched by Sea Launch on 24 Sept. 2008 to 97 degrees W: raumfahrer.net,
  "Kommunikationssatellit Galaxy 19 gestartet" and der-orion.com launch log (Sept. 2008),
  both from the Sea Launch and SS/L releases.
* SS/L 1300 solar arrays: one North and one South wing: Aviation Week, "SS/L reviewing
  other 1300 satellites after Intelsat 19 issue" (June 2012).

Estimated (no published figure found): the bus 2.4 m x 2.2 m x 3.4 m; each wing four
2.6 m x 2.3 m panels on a 1.8 m yoke, so the wings span 26.9 m tip to tip (within the
25-30 m of the SS/L 1300 class); the two 2.4 m deployed reflectors on the East and West
faces and their feed towers, the 1.0 m Earth-deck reflector, the OSR radiator sizes, the
apogee-engine nozzle.

Body frame: origin at the bus centre; +z the Earth deck (nadir, the payload's
boresight); +y North, the wing axis (wings North and South); +x East (the reflectors sit
on +x and -x, looking along +z after their boresight tilt). The seed turns the
solar-array drive angle.
"""

from __future__ import annotations

import numpy as np

from satsight.scene.primitives import Parts, pose, rot
from satsight.scene.replicas import parts as rp

BUS_M = (2.4, 2.2, 3.4)
WING_PANELS = 4
PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M = 2.6, 2.3, 1.8
REFLECTOR_DIAMETER_M = 2.4
DECK_REFLECTOR_DIAMETER_M = 1.0


def build(parts: Parts, rng: np.random.Generator) -> None:
    """Add Galaxy 19's parts (module docstring) to ``parts``; ``rng`` draws the drive."""
    bx, by, bz = BUS_M
    rp.mli_box(parts, "bus_mli", rp.MLI_GOLD, (bx, by, bz), (0, 0, 0))
    for k, sign in enumerate((1.0, -1.0), start=1):  # North and South OSR radiators
        rp.radiator(
            parts,
            f"radiator_{k}",
            rp.OSR,
            (0.9 * bx, 0.02, 0.8 * bz),
            (0, sign * (0.5 * by + 0.01), 0),
        )
    rp.plain_box(parts, "earth_deck", rp.MLI_BLACK, (bx, by, 0.02), (0, 0, 0.5 * bz + 0.01))
    top = 0.5 * bz + 0.02
    for k, (x, y) in enumerate(((0.7, 0.6), (0.7, -0.6), (-0.7, 0.6)), start=1):
        rp.cylinder(
            parts, f"feed_horn_{k}", rp.WHITE_PAINT, (x, y, top), (x, y, top + 0.5), 0.12, 32
        )
    # East/West reflectors: vertex beside the face, tilted to look towards nadir (+z)
    r = 0.5 * REFLECTOR_DIAMETER_M
    for k, sign in enumerate((1.0, -1.0), start=1):
        # concave side towards the bus and 20 degrees down towards nadir (+z)
        look = rot("y", -sign * np.deg2rad(70.0))
        vertex = (sign * (0.5 * bx + 0.35 + r), 0.0, 0.4)
        rp.add_dish(
            parts,
            f"reflector_{k}",
            REFLECTOR_DIAMETER_M,
            0.45 * REFLECTOR_DIAMETER_M,
            pose(look, vertex),
            rp.WHITE_PAINT,
            feed=False,
            thickness_m=0.04,
        )
        rp.cylinder(
            parts,
            f"reflector_{k}_arm",
            rp.CFRP,
            (sign * 0.5 * bx, 0.0, 0.4),
            (sign * (0.5 * bx + 0.35 + r), 0.0, 0.4),
            0.05,
        )
    rp.add_dish(
        parts,
        "deck_reflector",
        DECK_REFLECTOR_DIAMETER_M,
        0.4 * DECK_REFLECTOR_DIAMETER_M,
        pose(None, (-0.6, -0.5, top + 0.3)),
        rp.WHITE_PAINT,
        thickness_m=0.02,
    )
    rp.cylinder(
        parts, "deck_reflector_mast", rp.CFRP, (-0.6, -0.5, top), (-0.6, -0.5, top + 0.29), 0.04
    )
    rp.cylinder(
        parts, "apogee_nozzle", rp.TITANIUM, (0, 0, -0.5 * bz), (0, 0, -0.5 * bz - 0.35), 0.18, 32
    )
    rp.add_opposed_wings(
        parts, ("wing_north", "wing_south"), WING_PANELS, PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M,
        np.array([0.0, 0.5 * by + 0.02, 0.0]), rng,
    )  # fmt: skip
