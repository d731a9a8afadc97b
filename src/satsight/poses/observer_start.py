"""The observer's state at the epoch for the natural-motion modes of an SSPT plan.

Fly-around, fly-by, hover and RTN initial states are natural motion: the observer's initial
state is built in the target's RTN frame (``satsight.poses.relative_motion``) and then flown
with the same dynamics as the target. A closed relative orbit (fly-around, hover) gets its
velocity rescaled to the target's orbital energy, so that it does not drift along-track.
"""

from __future__ import annotations

import math

import numpy as np

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.orbits import J2, MU_EARTH_M3_S2, OrbitalElements, state_from_elements
from satsight.errors import SatsightError
from satsight.frames.orbital import inertial_from_relative_rtn
from satsight.poses import relative_motion as rm
from satsight.poses.plan_request import (
    FlyAround,
    FlyBy,
    Hover,
    OrbitalPlanRequest,
    OwnElements,
    RelativeRtn,
)


def mean_motion_rad_s(elements: OrbitalElements) -> float:
    """Mean motion of the orbit ``elements``, rad/s (two-body)."""
    return math.sqrt(MU_EARTH_M3_S2 / elements.semi_major_axis_m**3)


def _specific_energy(r: np.ndarray, v: np.ndarray, j2: bool) -> float:
    """Orbital energy per unit mass, J/kg, with the J2 potential when j2 is on."""
    rn = float(np.linalg.norm(r))
    energy = 0.5 * float(v @ v) - MU_EARTH_M3_S2 / rn
    if j2:
        sin_lat2 = (r[2] / rn) ** 2
        energy += (
            MU_EARTH_M3_S2
            / rn
            * J2
            * (EARTH_EQUATORIAL_RADIUS_M / rn) ** 2
            * 0.5
            * (3.0 * sin_lat2 - 1.0)
        )
    return energy


def _match_energy(
    r_obs: np.ndarray, v_obs: np.ndarray, r_target: np.ndarray, v_target: np.ndarray, j2: bool
) -> np.ndarray:
    """The observer's velocity rescaled so its orbital energy equals the target's.

    Equal energy means equal (mean) semi-major axis, hence no secular along-track drift: the
    linear Clohessy-Wiltshire initial state of a closed relative orbit drifts under the full
    dynamics by its second-order energy error, about 3 pi (dE / (n a)) per orbit.
    """
    target_energy = _specific_energy(r_target, v_target, j2)
    potential = _specific_energy(r_obs, np.zeros(3), j2)
    speed = math.sqrt(2.0 * (target_energy - potential))
    return v_obs * (speed / float(np.linalg.norm(v_obs)))


def observer_initial_state(
    request: OrbitalPlanRequest, r0: np.ndarray, v0: np.ndarray, elements: OrbitalElements
) -> tuple[np.ndarray, np.ndarray]:
    """The observer's inertial state at the epoch for a natural-motion mode."""
    motion = request.observer.motion
    n = mean_motion_rad_s(elements)
    j2 = request.propagation.j2
    if isinstance(motion, OwnElements):
        return state_from_elements(motion.elements)
    if isinstance(motion, Hover):
        # Same orbit, earlier (behind) or later (ahead) by the angle whose chord is the range.
        radius = float(np.linalg.norm(r0))
        if motion.range_m >= 2.0 * radius:
            raise SatsightError("hover range_km exceeds the target orbit's diameter")
        shift = 2.0 * math.asin(motion.range_m / (2.0 * radius))
        sign = -1.0 if motion.side == "behind" else 1.0
        shifted = OrbitalElements(
            elements.semi_major_axis_m,
            elements.eccentricity,
            elements.inclination_rad,
            elements.raan_rad,
            elements.arg_perigee_rad,
            elements.true_anomaly_rad + sign * shift,
        )
        r, v = state_from_elements(shifted)
        return r, _match_energy(r, v, r0, v0, j2)
    if isinstance(motion, FlyAround):
        rho, rho_dot = rm.fly_around_initial_state(motion.radius_m, n, phase_rad=motion.phase_rad)
        r, v = inertial_from_relative_rtn(r0, v0, rho, rho_dot)
        return r, _match_energy(r, v, r0, v0, j2)
    if isinstance(motion, FlyBy):
        rho, rho_dot = rm.fly_by_initial_state(
            motion.miss_distance_m, motion.start_along_track_m, n
        )
        return inertial_from_relative_rtn(r0, v0, rho, rho_dot)
    if isinstance(motion, RelativeRtn):
        return inertial_from_relative_rtn(r0, v0, motion.position_rtn_m, motion.velocity_rtn_m_s)
    raise SatsightError(f"observer motion {type(motion).__name__} is not natural motion")
