"""Earth orbits: classical elements, state vectors, and propagation with two-body + zonal gravity.

This module gathers the public names of the two stages it is built from:

* :mod:`satsight.ephemeris.elements`: :class:`OrbitalElements`, conversions
  :func:`state_from_elements` / :func:`elements_from_state`, :func:`orbital_period_s`,
  ``MU_EARTH_M3_S2``;
* :mod:`satsight.ephemeris.propagation`: :func:`propagate` (RK4 or DOP853),
  :func:`gravity_acceleration_m_s2`, the constants ``J2``,
  ``J3``, ``J4``.

Frame: every position and velocity is in GCRS (Earth-centred, ICRS axes). The zonal
gravity acts about the Earth's true pole (precession and nutation from skyfield, see
:mod:`satsight.ephemeris.earth_orientation`) when :func:`propagate` is given the epoch, and
about the GCRS z axis otherwise (an approximation: about 0.4 km after one LEO orbit at 2025,
0.9 km at 2050). Positions in m, velocities in m/s, times in s, angles in rad; float64.
"""

from satsight.ephemeris.elements import (
    MU_EARTH_M3_S2,
    OrbitalElements,
    elements_from_state,
    orbital_period_s,
    state_from_elements,
)
from satsight.ephemeris.propagation import (
    DOP853_ATOL_POSITION_M,
    DOP853_ATOL_VELOCITY_M_S,
    DOP853_RTOL,
    J2,
    J2_AXES,
    J3,
    J4,
    gravity_acceleration_m_s2,
    propagate,
)

__all__ = [
    "DOP853_ATOL_POSITION_M",
    "DOP853_ATOL_VELOCITY_M_S",
    "DOP853_RTOL",
    "J2",
    "J2_AXES",
    "J3",
    "J4",
    "MU_EARTH_M3_S2",
    "OrbitalElements",
    "elements_from_state",
    "gravity_acceleration_m_s2",
    "orbital_period_s",
    "propagate",
    "state_from_elements",
]
