"""Named tolerances of the tests, each in the unit its name gives.

A test imports the ones it compares with (``from tolerances import ONE_MM``) and keeps
tolerances that belong to one check (a quadrature's error, a published value's digits) beside
that check, with the reason for its size.
"""

from __future__ import annotations

import math

# Lengths, metres.
ONE_MM = 1e-3
ONE_UM = 1e-6
ONE_NM = 1e-9
# Speed, metres per second.
ONE_MM_S = 1e-3
# Time, seconds.
ONE_MS = 1e-3
# Image positions, pixels.
MICRO_PX = 1e-6
# Angles, radians.
ARCSEC_RAD = math.pi / (180.0 * 3600.0)
MAS_RAD = ARCSEC_RAD / 1000.0
