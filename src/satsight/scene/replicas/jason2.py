"""Jason-2 / OSTM (CNES/NASA/NOAA/EUMETSAT, 2008): Proteus bus and ocean altimetry payload.

Sources:

* PROTEUS bus, mass 525 kg, 511 W; payload Poseidon-3 altimeter, AMR radiometer, DORIS,
  GPSP, LRA: CNES, "JASON-2 satellite" (jason.cnes.fr).
* Launch mass 506 kg, 550 W, prime contractor Alcatel Space: TBS satellite encyclopedia,
  "Jason 2".
* A pair of deployable, tracking solar arrays on the same Proteus design: Wikipedia,
  "Jason-3".

Estimated (no published figure found here): the Proteus bus as a 1.0 m cube, the payload
module 1.0 x 1.0 x 1.0 m, the Poseidon-3 dish 1.2 m (the Poseidon-2 size of Jason-1), the
AMR's 0.75 m reflector, each wing's four 0.8 m x 0.6 m panels on a 0.5 m yoke (an 8.7 m
span), the DORIS antenna, laser retroreflector ring and radiators.

Body frame: origin at the centre of the bus + payload stack; +z nadir, the altimeter's
boresight (the dish on the payload's +z deck looks along +z); wings along +y and -y.
The seed turns the solar-array drive angle.
"""

from __future__ import annotations

import numpy as np

from satsight.scene.primitives import Parts, pose, rot
from satsight.scene.replicas import parts as rp

BUS_M = (1.0, 1.0, 1.0)
PAYLOAD_M = (1.0, 1.0, 1.0)
ALTIMETER_DIAMETER_M = 1.2
AMR_DIAMETER_M = 0.75
WING_PANELS = 4
PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M = 0.8, 0.6, 0.5


def build(parts: Parts, rng: np.random.Generator) -> None:
    """Add Jason-2's parts (module docstring) to ``parts``; ``rng`` draws the drive."""
    h = BUS_M[2] + PAYLOAD_M[2]
    bottom, split, top = -0.5 * h, -0.5 * h + BUS_M[2], 0.5 * h
    rp.mli_box(parts, "bus_mli", rp.MLI_GOLD, BUS_M, (0, 0, bottom + 0.5 * BUS_M[2]))
    rp.mli_box(parts, "payload_mli", rp.MLI_SILVER, PAYLOAD_M, (0, 0, split + 0.5 * PAYLOAD_M[2]))
    for k, sign in enumerate((1.0, -1.0), start=1):
        rp.radiator(parts, f"radiator_{k}", rp.OSR, (0.02, 0.7, 0.7), (sign * 0.51, 0, split + 0.5))
    rp.add_dish(
        parts,
        "altimeter_dish",
        ALTIMETER_DIAMETER_M,
        0.35 * ALTIMETER_DIAMETER_M,
        pose(None, (0, 0, top + 0.05)),
        rp.WHITE_PAINT,
    )
    rp.cylinder(parts, "altimeter_mount", rp.ALUMINIUM, (0, 0, top), (0, 0, top + 0.05), 0.2)
    # AMR: an offset reflector on the -x side of the deck, tilted 30 degrees off nadir
    rp.add_dish(
        parts,
        "amr_reflector",
        AMR_DIAMETER_M,
        0.4 * AMR_DIAMETER_M,
        pose(rot("y", -np.deg2rad(30.0)), (-0.65, 0.0, top - 0.1)),
        rp.WHITE_PAINT,
        feed=False,
        thickness_m=0.02,
    )
    rp.plain_box(
        parts, "amr_electronics", rp.MLI_SILVER, (0.25, 0.3, 0.25), (-0.35, 0.3, top + 0.125)
    )
    rp.cylinder(
        parts, "doris_antenna", rp.WHITE_PAINT, (0.3, -0.3, bottom), (0.3, -0.3, bottom - 0.4), 0.04
    )
    ring = rp.hexagonal_prism(0.25, top, top + 0.06)
    ring.apply_translation((0.35, -0.35, 0.0))
    parts.add("laser_retroreflector", rp.ALUMINIUM, ring)
    rp.add_opposed_wings(
        parts, ("wing_1", "wing_2"), WING_PANELS, PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M,
        np.array([0.0, 0.5 * BUS_M[1], bottom + 0.5 * BUS_M[2]]), rng,
    )  # fmt: skip
