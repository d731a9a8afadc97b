"""ICESat-2 (NASA, 2018): LEOStar-3 bus, the ATLAS laser altimeter and one solar wing.

Sources:

* Stowed envelope 2.5 x 1.9 x 3.8 m, launch mass 1514 kg, 1200 W, LEOStar-3 bus by Orbital
  ATK: NASA ICESat-2 launch press kit (Sept. 2018), as given in the Wikipedia infobox
  "ICESat-2".
* ATLAS receiver telescope: a 2.6 ft (0.79 m), 46 lb beryllium telescope on the optical
  bench: NASA GSFC, "NASA lining up ICESat-2's laser-catching telescope" (Nov. 2014).
* One solar-array wing, 3818 W at end of life: Orbital ATK ICESat-2 fact sheet, as quoted
  in the raumfahrer.net forum thread on the launch (2018).

Estimated (no published figure found): the split of the stowed stack into a 2.0 m bus and
a 1.8 m ATLAS box, the wing's four 1.6 m x 1.9 m panels and its 0.6 m yoke, the sizes
and places of the star trackers, antennas and radiators.

Body frame: origin at the centre of the stowed stack; +z the ATLAS end, where the
telescope looks out (boresight +z); +y the wing axis (the wing deploys from the bus's +y
face); +x completes the frame. The seed turns the solar-array drive angle.
"""

from __future__ import annotations

import numpy as np

from satsight.scene.primitives import Parts
from satsight.scene.replicas import parts as rp

ENVELOPE_M = (1.9, 2.5, 3.8)
TELESCOPE_DIAMETER_M = 0.79
WING_PANELS = 4
PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M = 1.6, 1.9, 0.6


def build(parts: Parts, rng: np.random.Generator) -> None:
    """Add ICESat-2's parts (module docstring) to ``parts``; ``rng`` draws the drive angle."""
    sx, sy, sz = ENVELOPE_M
    bottom, top = -0.5 * sz, 0.5 * sz
    z_split = bottom + 2.0  # bus below, ATLAS above
    atlas_top = top - 0.3  # the telescope's barrel stands 0.3 m proud of the ATLAS box
    bus_z = (bottom + 0.01, z_split)  # the black crinkle closes the bottom 10 mm
    bus_centre = (0, 0, 0.5 * sum(bus_z))
    rp.mli_box(parts, "bus_mli", rp.MLI_GOLD, (sx - 0.04, sy, bus_z[1] - bus_z[0]), bus_centre)
    atlas_h = atlas_top - z_split
    atlas_centre = (0, 0, z_split + 0.5 * atlas_h)
    rp.mli_box(parts, "atlas_mli", rp.MLI_SILVER, (sx - 0.04, sy, atlas_h), atlas_centre)
    for k, sign in enumerate((1.0, -1.0), start=1):
        x = sign * (0.5 * sx - 0.01)
        rp.radiator(
            parts,
            f"atlas_radiator_{k}",
            rp.WHITE_PAINT,
            (0.02, 0.8 * sy, 0.8 * atlas_h),
            (x, 0, atlas_centre[2]),
        )
        rp.radiator(
            parts, f"bus_radiator_{k}", rp.OSR, (0.02, 0.6 * sy, 1.2), (x, 0, bus_centre[2])
        )
    r_tel = 0.5 * TELESCOPE_DIAMETER_M
    xy = (-0.25, 0.35)
    rp.cylinder(
        parts, "telescope_barrel", rp.BLACK_PAINT, (*xy, atlas_top), (*xy, top - 0.01), r_tel, 64
    )
    rp.cylinder(
        parts, "telescope_aperture", rp.MLI_BLACK, (*xy, top - 0.01), (*xy, top), r_tel - 0.02, 64
    )
    rp.cylinder(
        parts,
        "laser_beam_expander",
        rp.ALUMINIUM,
        (0.55, -0.6, atlas_top),
        (0.55, -0.6, atlas_top + 0.25),
        0.08,
    )
    for k, x in enumerate((-0.6, 0.2), start=1):
        rp.plain_box(
            parts, f"star_tracker_{k}", rp.ANODISED, (0.18, 0.18, 0.22), (x, -0.9, atlas_top + 0.11)
        )
    rp.plain_box(
        parts, "bus_crinkle", rp.BLACK_PAINT, (0.9 * sx, 0.9 * sy, 0.01), (0, 0, bottom + 0.005)
    )
    rp.cylinder(
        parts, "s_band_antenna", rp.WHITE_PAINT, (0.6, 0.9, bottom), (0.6, 0.9, bottom - 0.12), 0.06
    )
    rp.add_wing(
        parts,
        "wing",
        WING_PANELS,
        PANEL_LENGTH_M,
        PANEL_WIDTH_M,
        YOKE_M,
        rp.TO_PLUS_Y,
        (0, 0.5 * sy, bus_centre[2]),
        rng.uniform(-np.pi / 3, np.pi / 3),
    )
