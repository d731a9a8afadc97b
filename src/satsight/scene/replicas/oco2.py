"""OCO-2 (NASA/JPL, 2014): LEOStar-2 hexagonal bus, the three-band spectrometer, two wings.

Sources:

* Stowed size 2.12 m x 0.94 m, launch mass 454 kg, 815 W, LEOStar-2 bus by Orbital
  Sciences: Orbital Sciences OCO-2 fact sheet, as given in the Wikipedia infobox "Orbiting
  Carbon Observatory 2".
* Structure of honeycomb panels forming a hexagon (SORCE and GALEX heritage), S-band
  antenna, X-band transmitter, star tracker, four reaction wheels, solar arrays that keep
  facing the Sun: JPL, "OCO-2 Observatory: Spacecraft" (oco.jpl.nasa.gov).
* The instrument's f/1.8 Cassegrain telescope: same infobox (Crisp et al.).

Estimated: the two wings of two 1.1 m x 0.8 m panels on 0.35 m yokes, the telescope's
0.11 m aperture and sunshade, the instrument box, antennas and radiator sizes.

Body frame: origin at the centre of the hexagonal prism (axis along z, two corners on
+/-x, 0.94 m across the corners, 2.12 m long); +z the instrument end, where the
telescope looks out (boresight +z); wings along +y and -y; the seed turns the drive angle.
"""

from __future__ import annotations

import numpy as np

from satsight.scene.primitives import Parts
from satsight.scene.replicas import parts as rp

HEIGHT_M = 2.12
ACROSS_CORNERS_M = 0.94
WING_PANELS = 2
PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M = 1.1, 0.8, 0.35


def build(parts: Parts, rng: np.random.Generator) -> None:
    """Add OCO-2's parts (module docstring) to ``parts``; ``rng`` draws the drive angle."""
    h = HEIGHT_M
    bottom, top = -0.5 * h, 0.5 * h
    parts.add("bus_mli", rp.MLI_GOLD, rp.hexagonal_prism(ACROSS_CORNERS_M, bottom + 0.06, 0.15))
    parts.add("instrument_mli", rp.MLI_SILVER, rp.hexagonal_prism(ACROSS_CORNERS_M, 0.15, top))
    ring = rp.hexagonal_prism(0.6, bottom, bottom + 0.06)
    parts.add("launch_adapter_ring", rp.ALUMINIUM, ring)
    # the hexagon's flat faces lie at +/- apothem along y
    apothem = 0.5 * ACROSS_CORNERS_M * np.cos(np.pi / 6)
    rp.radiator(parts, "radiator", rp.OSR, (0.3, 0.02, 0.8), (0.0, -(apothem + 0.01), top - 0.55))
    aperture_xy = (0.12, 0.1)
    rp.cylinder(
        parts,
        "telescope_sunshade",
        rp.BLACK_PAINT,
        (*aperture_xy, top),
        (*aperture_xy, top + 0.12),
        0.075,
        48,
    )
    rp.cylinder(
        parts,
        "telescope_aperture",
        rp.MLI_BLACK,
        (*aperture_xy, top + 0.12),
        (*aperture_xy, top + 0.125),
        0.055,
        48,
    )
    rp.plain_box(parts, "star_tracker", rp.ANODISED, (0.12, 0.12, 0.16), (-0.2, -0.1, top + 0.08))
    rp.cylinder(
        parts, "s_band_antenna", rp.WHITE_PAINT, (0.2, 0.0, bottom), (0.2, 0.0, bottom - 0.1), 0.05
    )
    rp.cylinder(
        parts,
        "x_band_antenna",
        rp.WHITE_PAINT,
        (-0.2, 0.0, bottom),
        (-0.2, 0.0, bottom - 0.08),
        0.07,
    )
    rp.add_opposed_wings(
        parts, ("wing_1", "wing_2"), WING_PANELS, PANEL_LENGTH_M, PANEL_WIDTH_M, YOKE_M,
        np.array([0.0, apothem, -0.2]), rng,
    )  # fmt: skip
