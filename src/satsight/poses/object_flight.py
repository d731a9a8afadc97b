"""Objects on their own flight beside the target: where each is, and how it is turned, in
the target's body frame at each frame.

An object that flies (``ObjectFlight``) starts at the epoch either on its own osculating
``elements`` or at a state relative to the target in the target's RTN frame
(``position_rtn_m``, ``velocity_rtn_m_s`` about the target's body origin, the observer's
``relative_rtn`` form), and is propagated exactly as the target and the observer are
(``satsight.poses.plan.fly``). Its body frame turns by an ``AttitudeLaw`` of its own
(LVLH-fixed about its own orbit, inertial or spinning; ``satsight.poses.attitude``). With
a TLE/OMM/OEM target an RTN start is flown with our dynamics beside the target flown from
its epoch state, and the relative motion is carried, in RTN, onto the target's real
trajectory (as the plan does for a relative observer); an object on its own elements
flies them as they are.

What the renderer needs is the object's pose in the target's body frame,

    x_body = R_body_from_object x_object + t_body_m,
    R_body_from_object = R_body_from_gcrs R_gcrs_from_object,
    t_body_m = R_body_from_gcrs (r_object - r_target),

with r the GCRS positions of the two body origins. Within an exposure (|tau| <= 0.1 s) the
pose is carried by constant rates, as the camera's (``satsight.poses.pose_rates``):

    R(tau) = Exp(-w_b tau) R(0) Exp(w_o tau),   t(tau) = Exp(-w_b tau) (t(0) + u tau),

with w_b the target's inertial angular velocity in body axes, w_o the object's in object
axes, and u = R_body_from_gcrs (v_object - v_target) the relative velocity in body axes at
the frame (from the two states). The object's rate comes from a forward difference of its
attitude law over ``RATE_STEP_S`` with the object moved along its velocity (exact for the
constant rates of the inertial and spinning laws, O(h) of the orbital rate for the
LVLH-fixed one); nothing is propagated past the frames' times. The neglected relative
acceleration,
~n^2 |rho| = 1.2e-6 s^-2 x |rho| in low orbit, moves an object 100 m away by 6e-7 m in 0.1 s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from satsight.ephemeris.orbits import OrbitalElements, state_from_elements
from satsight.errors import SatsightError
from satsight.frames.orbital import inertial_from_relative_rtn, relative_rtn
from satsight.frames.quaternion import matrix_from_quaternion, quaternion_from_matrix
from satsight.frames.rigid import RigidTransform
from satsight.poses.plan import attitude_quaternions, fly, target_start, target_states
from satsight.poses.plan_request import AttitudeLaw, OrbitalPlanRequest, PlanRequest
from satsight.poses.pose_rates import RATE_STEP_S, rotation_from_vector, rotation_vector


@dataclass(frozen=True)
class ObjectFlight:
    """An object's own flight: its start at the epoch and its attitude law.

    elements: its own osculating elements, or None for a start relative to the target:
    position_rtn_m (3,), m, and velocity_rtn_m_s (3,), m/s, in the target's RTN frame about
    its body origin. attitude: how its body frame turns (``AttitudeLaw``).
    """

    elements: OrbitalElements | None
    position_rtn_m: np.ndarray | None
    velocity_rtn_m_s: np.ndarray | None
    attitude: AttitudeLaw

    def __post_init__(self) -> None:
        if (self.elements is None) == (self.position_rtn_m is None):
            raise SatsightError("an object's flight starts from elements or an RTN state, not both")


@dataclass(frozen=True)
class ObjectPoses:
    """One flying object's pose in the target's body frame at each frame, and its rates.

    R_body_from_object (N, 3, 3); t_body_m (N, 3), m; velocity_body_m_s (N, 3): the
    relative velocity in the target's body axes, m/s; omega_object_rad_s (N, 3): the
    object's inertial angular velocity in its own axes, rad/s.
    """

    R_body_from_object: np.ndarray
    t_body_m: np.ndarray
    velocity_body_m_s: np.ndarray
    omega_object_rad_s: np.ndarray

    def target_from_object(
        self, index: int, offset_s: float = 0.0, omega_body_rad_s: np.ndarray | None = None
    ) -> RigidTransform:
        """The pose at frame ``index`` moved by ``offset_s`` (module docstring);
        omega_body_rad_s: the target's inertial angular velocity in body axes at the frame
        (``PoseTrack.omega_body_rad_s``), needed when offset_s is not 0."""
        R, t = self.R_body_from_object[index], self.t_body_m[index]
        if offset_s != 0.0:
            if omega_body_rad_s is None:
                raise SatsightError("an offset pose needs the target's angular velocity")
            turn = rotation_from_vector(-np.asarray(omega_body_rad_s) * offset_s)
            spin = rotation_from_vector(self.omega_object_rad_s[index] * offset_s)
            R = turn @ R @ spin
            t = turn @ (t + self.velocity_body_m_s[index] * offset_s)
        return RigidTransform(R, t)


def _object_states(
    request: OrbitalPlanRequest,
    flight: ObjectFlight,
    times_s: np.ndarray,
    r_t: np.ndarray,
    v_t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The object's GCRS positions and velocities (N, 3) at ``times_s`` (ascending)."""
    if flight.elements is not None:
        return fly(request, *state_from_elements(flight.elements), times_s)
    r0, v0, _ = target_start(request)
    start = inertial_from_relative_rtn(r0, v0, flight.position_rtn_m, flight.velocity_rtn_m_s)
    r_o, v_o = fly(request, *start, times_s)
    if request.target.elements is None:  # carried onto the target's real trajectory
        rho, rho_dot = relative_rtn(*fly(request, r0, v0, times_s), r_o, v_o)
        r_o, v_o = inertial_from_relative_rtn(r_t, v_t, rho, rho_dot)
    return r_o, v_o


def object_poses(
    request: PlanRequest, flights: list[ObjectFlight], times_s: np.ndarray
) -> list[ObjectPoses]:
    """Each flying object's poses at the frames' ``times_s`` (N,), s after the epoch (any
    order, >= 0)."""
    if not flights:
        return []
    if not isinstance(request, OrbitalPlanRequest):
        raise SatsightError(
            "objects on their own flight need frames planned from orbits (epoch_utc, the "
            "target's orbit and a sampler); with frames placed by hand, place objects by "
            "offset_m and q_target_from_object"
        )
    times = np.asarray(times_s, dtype=np.float64).reshape(-1)
    if times.size and (not np.all(np.isfinite(times)) or times.min() < 0):
        raise SatsightError("object flights are computed at finite times >= 0 s")
    # The frames' times, propagated once in time order (no later instant: a TLE or OEM
    # target may end at the last frame).
    order = np.argsort(times, kind="stable")
    sorted_times = times[order]
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    r_t, v_t = target_states(request, sorted_times)
    R_gcrs_from_body = matrix_from_quaternion(
        attitude_quaternions(request.attitude, r_t, v_t, sorted_times)
    )
    R_body_from_gcrs = np.swapaxes(R_gcrs_from_body, -1, -2)
    poses = []
    for flight in flights:
        r_o, v_o = _object_states(request, flight, sorted_times, r_t, v_t)
        R_gcrs_from_object = matrix_from_quaternion(
            attitude_quaternions(flight.attitude, r_o, v_o, sorted_times)
        )
        # Object-axis rate, R(t + h) = R(t) Exp(w h), with the object moved along its
        # velocity for the attitude a step later (as the plan's rates are taken).
        R_later = matrix_from_quaternion(
            attitude_quaternions(
                flight.attitude, r_o + v_o * RATE_STEP_S, v_o, sorted_times + RATE_STEP_S
            )
        )
        step = np.swapaxes(R_gcrs_from_object, -1, -2) @ R_later
        omega = rotation_vector(quaternion_from_matrix(step)) / RATE_STEP_S
        R_body_from_object = (R_body_from_gcrs @ R_gcrs_from_object)[back]
        t_body = np.einsum("nij,nj->ni", R_body_from_gcrs, r_o - r_t)[back]
        u_body = np.einsum("nij,nj->ni", R_body_from_gcrs, v_o - v_t)[back]
        poses.append(ObjectPoses(R_body_from_object, t_body, u_body, omega[back]))
    return poses
