"""What a frame plan is asked for: the typed, SI inputs of ``satsight.poses.plan``.

Two kinds of request:

- ``ViewsPlanRequest``: views in the target's body frame, with the Sun, the Earth and the
  Moon placed by hand.
- ``OrbitalPlanRequest``: frames planned from orbits: the target's trajectory and attitude
  law from an epoch, the observer's motion (SSPT) or RSSF's distance intervals, the
  visibility rule and the propagator's settings.

``satsight.config`` builds them from a scenario; the plan never sees the scenario itself.
Also here: the default span of an SSPT plan (``natural_span_s``), which the scenario's size
check uses too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from skyfield.timelib import Time

from satsight.ephemeris.orbits import MU_EARTH_M3_S2, OrbitalElements, orbital_period_s
from satsight.ephemeris.visibility import VisibilityLimits
from satsight.errors import SatsightError
from satsight.frames.rigid import RigidTransform
from satsight.poses.distance_intervals import DistanceInterval
from satsight.poses.views import View

# --- views in the body frame ---------------------------------------------------------------


@dataclass(frozen=True)
class ViewsPlanRequest:
    """Frames given in the target's body frame, with the Sun, the Earth and the Moon placed
    by hand (no orbit, no epoch, no visibility tests).

    frames: per frame a ``View`` (the camera looks at the target's box centre) or the pose
    x_cam = R x_body + t as a ``RigidTransform``. sun_direction_body: (3,) unit vector from
    the target towards the Sun, body frame. sun_distance_m: the Sun's distance, m.
    earth_center_from_target_m, moon_center_from_target_m: (3,) vectors from the target to
    the body's centre in the body frame, m, or None where the scene has no such body.
    """

    frames: tuple[View | RigidTransform, ...]
    sun_direction_body: np.ndarray
    sun_distance_m: float
    earth_center_from_target_m: np.ndarray | None = None
    moon_center_from_target_m: np.ndarray | None = None


# --- frames planned from orbits ------------------------------------------------------------


class TrajectoryStates(Protocol):
    """A trajectory given as states: SGP4 elements (TLE, OMM) or an OEM ephemeris."""

    def state_gcrs(self, times: Time) -> tuple[np.ndarray, np.ndarray]:
        """GCRS positions (N, 3), m, and velocities (N, 3), m/s, at ``times`` (N,)."""
        ...


@dataclass(frozen=True)
class TargetTrajectory:
    """The target's flight: osculating ``elements`` at the epoch (propagated), or ``states``
    (SGP4 elements or an OEM file, followed as they are); exactly one of them.

    semi_major_axis_m: the orbit's semi-major axis, m (the elements', SGP4's mean one, or the
    osculating one of an OEM's first state): it sets the target's period for the default
    SSPT span and for frames taken every ``step_deg``.
    """

    semi_major_axis_m: float
    elements: OrbitalElements | None = None
    states: TrajectoryStates | None = None

    def __post_init__(self) -> None:
        if (self.elements is None) == (self.states is None):
            raise SatsightError("a target trajectory is either elements or states, not both")


@dataclass(frozen=True)
class AttitudeLaw:
    """How the target's body frame turns (see ``satsight.poses.attitude``).

    law: ``lvlh_fixed`` (q_ref_from_body = q_lvlh_from_body), ``inertial`` (q_gcrs_from_body)
    or ``spinning`` (q_gcrs_from_body at the epoch, turning at ``rate_body_rad_s``).
    q_ref_from_body: (4,) unit quaternion, scalar first. rate_body_rad_s: (3,) body-frame
    angular rate, rad/s.
    """

    law: str
    q_ref_from_body: np.ndarray
    rate_body_rad_s: np.ndarray


@dataclass(frozen=True)
class FlyAround:
    """A natural closed relative orbit of radius ``radius_m`` (Clohessy-Wiltshire), starting
    at ``phase_rad`` on it."""

    radius_m: float
    phase_rad: float


@dataclass(frozen=True)
class FlyBy:
    """A co-elliptic pass ``miss_distance_m`` above (> 0) or below the target's orbit,
    starting ``start_along_track_m`` along-track from the target."""

    miss_distance_m: float
    start_along_track_m: float


@dataclass(frozen=True)
class Approach:
    """A guided spiral from ``start_range_m`` to ``end_range_m`` in ``revolutions`` turns,
    passing ``via_ranges_m`` (the interval edges crossed) at equal time steps."""

    start_range_m: float
    end_range_m: float
    revolutions: float
    via_ranges_m: tuple[float, ...]


@dataclass(frozen=True)
class Hover:
    """Station keeping on the target's orbit, ``range_m`` (chord) ``ahead`` or ``behind``."""

    range_m: float
    side: str


@dataclass(frozen=True)
class OwnElements:
    """The observer on its own orbit: osculating ``elements`` at the epoch, propagated."""

    elements: OrbitalElements


@dataclass(frozen=True)
class RelativeRtn:
    """The observer's initial state relative to the target, in the target's RTN frame:
    position (3,), m, and velocity (3,), m/s."""

    position_rtn_m: np.ndarray
    velocity_rtn_m_s: np.ndarray


@dataclass(frozen=True)
class OwnTrajectory:
    """The observer follows its own TLE, OMM (SGP4) or OEM ``states``."""

    states: TrajectoryStates


ObserverMotion = FlyAround | FlyBy | Approach | Hover | OwnElements | RelativeRtn | OwnTrajectory


@dataclass(frozen=True)
class Observer:
    """The SSPT observer: its ``motion`` and how its camera rolls about the boresight
    (``camera_roll``, a policy of ``satsight.poses.attitude``, then ``roll_rad`` more)."""

    motion: ObserverMotion
    camera_roll: str
    roll_rad: float


@dataclass(frozen=True)
class SsptSampler:
    """Sequential frames along the observer's trajectory from ``start_s`` after the epoch
    for ``duration_s`` (None: the natural span, see ``natural_span_s``): ``frame_count``
    uniform samples, one every ``step_s`` seconds or, for a fly-around, one every
    ``step_deg`` degrees of its revolution (exactly one of the three)."""

    start_s: float
    duration_s: float | None
    frame_count: int | None
    step_s: float | None
    step_deg: float | None


@dataclass(frozen=True)
class RssfSampler:
    """``frame_count`` views at the epoch on seeded spherical Fibonacci lattices, one per
    distance interval; ``distance_distribution`` draws ranges in an interval; ``camera_roll``
    is the roll policy's reference."""

    frame_count: int
    seed: int
    intervals: tuple[DistanceInterval, ...]
    distance_distribution: str
    camera_roll: str


@dataclass(frozen=True)
class Propagation:
    """How both spacecraft are propagated (``satsight.ephemeris.propagation.propagate``):
    ``method`` rk4 at ``step_s`` seconds or dop853, ``j2`` on or off about ``j2_axis``
    (``true_pole`` or ``gcrs_z``), zonal terms up to ``max_zonal_degree``."""

    method: str
    step_s: float
    j2: bool
    j2_axis: str
    max_zonal_degree: int


@dataclass(frozen=True)
class VisibilityRule:
    """Which frames count as observable (``limits``) and what happens to the others:
    ``on_fail`` ``flag`` (kept, flagged), ``skip`` (not rendered) or ``keep`` (no limits)."""

    limits: VisibilityLimits
    on_fail: str


@dataclass(frozen=True)
class OrbitalPlanRequest:
    """Frames planned from orbits, from ``epoch_utc`` (ISO 8601 UTC).

    observer: the SSPT observer (None with an RSSF sampler, which places the camera).
    """

    epoch_utc: str | None
    target: TargetTrajectory
    attitude: AttitudeLaw
    sampler: SsptSampler | RssfSampler
    observer: Observer | None
    visibility: VisibilityRule
    propagation: Propagation


PlanRequest = ViewsPlanRequest | OrbitalPlanRequest


def natural_span_s(semi_major_axis_m: float, motion: ObserverMotion) -> float:
    """The default length of an SSPT span for an observer's motion, s: one target orbit, a
    fly-by's whole pass (4 y0 / (3 n x0)), or an approach's ``revolutions`` orbits.

    semi_major_axis_m: the target orbit's semi-major axis, m.
    """
    a_m = semi_major_axis_m
    period = orbital_period_s(a_m)
    if isinstance(motion, FlyBy):
        n = math.sqrt(MU_EARTH_M3_S2 / a_m**3)
        drift_m_s = 1.5 * n * abs(motion.miss_distance_m)
        return 2.0 * abs(motion.start_along_track_m) / drift_m_s
    if isinstance(motion, Approach):
        return motion.revolutions * period
    return period
