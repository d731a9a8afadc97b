"""The frame plan: from what a scenario asks for to a ``PoseTrack``.

Two sources of frames:

- **Views in the body frame** (``frames:``): each frame places the camera by distance,
  azimuth, elevation and roll about the target; the Sun, the Earth and the Moon are placed by
  hand in the body frame. No orbit and no visibility tests.
- **Frames planned from orbits** (``sampler:``): the target flies on ``orbit`` from
  ``epoch_utc`` (or follows a TLE / OMM with SGP4, or an OEM ephemeris file) and turns by its
  ``attitude`` law; the Sun and the Moon come from the DE421 ephemeris; the Earth is at the
  origin of GCRS. With a TLE/OMM/OEM target the relative modes start from its state at the
  epoch: their relative motion is flown with our dynamics and carried, in the target's RTN
  frame, onto the target's real trajectory. An observer may also follow its own TLE, OMM or
  OEM (modes ``tle``, ``omm``, ``oem``).

  - ``sspt``: the observer follows its operational mode (fly-around, fly-by, approach, hover,
    its own elements or an RTN initial state) and frames are taken at uniform times.
    Fly-around, fly-by, hover and RTN initial states are natural motion: the observer's
    initial state is built in the target's RTN frame and both spacecraft are propagated with
    the same dynamics (two-body + J2, RK4 at 1 s by default). The approach is a guided spiral
    (it needs thrust), placed kinematically in RTN, by default with equal time in each
    distance interval it crosses.
  - ``rssf``: all frames at the epoch; the camera is placed about the target on seeded
    spherical Fibonacci lattices (body frame), one per distance interval, with a random roll.

The camera always looks at the target's bounding-box centre; its roll about the boresight
follows the observer's ``camera_roll`` policy (see ``satsight.poses.attitude``).

The plan is asked for with a ``satsight.poses.plan_request.PlanRequest`` (typed, SI), which
``satsight.config`` builds from a scenario.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from satsight.ephemeris.earth_orientation import R_itrs_from_gcrs
from satsight.ephemeris.occultation import inside_earth
from satsight.ephemeris.orbits import (
    OrbitalElements,
    elements_from_state,
    orbital_period_s,
    propagate,
    state_from_elements,
)
from satsight.ephemeris.sun_moon import moon_position_gcrs_m, sun_position_gcrs_m
from satsight.ephemeris.time import epoch_times, format_epoch_utc
from satsight.ephemeris.visibility import assess_visibility
from satsight.ephemeris.wgs84 import geodetic_height_m
from satsight.errors import SatsightError
from satsight.frames.orbital import inertial_from_relative_rtn, relative_rtn, rtn_from_inertial
from satsight.frames.quaternion import matrix_from_quaternion, quaternion_conjugate
from satsight.poses import relative_motion as rm
from satsight.poses.attitude import (
    cam_from_body,
    camera_reference,
    inertial_attitude,
    lvlh_fixed_attitude,
    pointing_gcrs_from_cam,
    spinning_attitude,
)
from satsight.poses.distance_intervals import default_intervals, interval_names_for_ranges
from satsight.poses.observer_start import mean_motion_rad_s, observer_initial_state
from satsight.poses.plan_request import (
    Approach,
    AttitudeLaw,
    FlyAround,
    Hover,
    OrbitalPlanRequest,
    OwnElements,
    OwnTrajectory,
    PlanRequest,
    RssfSampler,
    TrajectoryStates,
    ViewsPlanRequest,
    natural_span_s,
)
from satsight.poses.pose_rates import RATE_STEP_S, body_rate_rad_s
from satsight.poses.rssf import rssf_samples
from satsight.poses.sspt import sspt_angle_times_s, sspt_times_s
from satsight.poses.track import FLAG_FIELDS, RATE_FIELDS, PoseTrack
from satsight.poses.view_track import views_track

# Frames planned together past the flight (see `_orbital_track`): the Earth's orientation
# takes ~22 kB a frame while skyfield computes it, so a chunk holds ~100 MB at most.
PLAN_CHUNK_FRAMES = 4096


def plan_track(
    request: PlanRequest, target_center_body_m: np.ndarray, target_radius_m: float = 0.0
) -> PoseTrack:
    """Every frame ``request`` asks for (before the visibility policy drops any).

    target_center_body_m: (3,) the target's bounding-box centre in the body frame, m; the
    camera looks at it. target_radius_m: the radius of the target's bounding sphere about
    that centre, m; a frame that puts the camera inside it, or inside the Earth, is an
    error.
    """
    center = np.asarray(target_center_body_m, dtype=np.float64).reshape(3)
    if isinstance(request, ViewsPlanRequest):
        track = views_track(request, center)
    else:
        track = _orbital_track(request, center)
    inside = np.flatnonzero(track.range_m <= target_radius_m)
    if inside.size:
        i = int(inside[0])
        raise SatsightError(
            f"frame {i} (t = {track.time_s[i]:.1f} s) puts the camera {track.range_m[i]:.3g} m "
            f"from the target's centre, inside its bounding sphere ({target_radius_m:.3g} m); "
            "move the observer further away"
        )
    return track


def frames_to_render(request: PlanRequest, track: PoseTrack) -> np.ndarray:
    """Indices of the planned frames that are rendered under the visibility policy."""
    if isinstance(request, OrbitalPlanRequest) and request.visibility.on_fail == "skip":
        return np.flatnonzero(track.visible)
    return np.arange(len(track))


# --- frames planned from orbits ------------------------------------------------------------


def _natural_span_s(request: OrbitalPlanRequest) -> float:
    """The default length of the request's SSPT span for its observer's motion, s."""
    return natural_span_s(request.target.semi_major_axis_m, request.observer.motion)


def _sspt_times(request: OrbitalPlanRequest) -> np.ndarray:
    sampler = request.sampler
    duration = sampler.duration_s or _natural_span_s(request)
    start, end = sampler.start_s, sampler.start_s + duration
    if sampler.step_deg is not None:
        period = orbital_period_s(request.target.semi_major_axis_m)
        # The fly-around turns 360 degrees per target orbit from the start of the span.
        stop_deg = 360.0 * duration / period
        return sspt_angle_times_s(period, 0.0, stop_deg, sampler.step_deg, start_s=start)
    # Over one whole orbit a fly-around or a hover comes back to its start: leave the
    # repeated view out.
    closed = isinstance(request.observer.motion, FlyAround | Hover) and sampler.duration_s is None
    if sampler.frame_count is not None and sampler.frame_count > 1 and closed:
        return sspt_times_s(start, end, frame_count=sampler.frame_count, include_end=False)
    return sspt_times_s(start, end, frame_count=sampler.frame_count, step_s=sampler.step_s)


def _target_attitude(
    request: OrbitalPlanRequest, r: np.ndarray, v: np.ndarray, times_s: np.ndarray
) -> np.ndarray:
    return attitude_quaternions(request.attitude, r, v, times_s)


def attitude_quaternions(
    attitude: AttitudeLaw, r: np.ndarray, v: np.ndarray, times_s: np.ndarray
) -> np.ndarray:
    """(N, 4) q_gcrs_from_body of a body on the states ``r``, ``v`` (N, 3) at ``times_s``
    (N,) s after the epoch, turning by ``attitude``."""
    q_ref = attitude.q_ref_from_body
    if attitude.law == "lvlh_fixed":
        return lvlh_fixed_attitude(r, v, q_ref)
    if attitude.law == "inertial":
        return inertial_attitude(q_ref, len(times_s))
    return spinning_attitude(q_ref, attitude.rate_body_rad_s, times_s)


def _trajectory_states(
    states: TrajectoryStates, request: OrbitalPlanRequest, times_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """GCRS positions (N, 3), m, and velocities (N, 3), m/s, of a TLE/OMM (SGP4) or OEM
    (interpolated) trajectory at ``times_s`` (N,) s after the request's epoch."""
    return states.state_gcrs(epoch_times(request.epoch_utc, times_s))


def fly(
    request: OrbitalPlanRequest, r_start: np.ndarray, v_start: np.ndarray, times_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """GCRS positions and velocities (N, 3) at ``times_s`` (N,) (ascending, >= 0) of a
    craft starting at ``r_start``, ``v_start`` at the epoch, propagated as the request's
    spacecraft are."""
    prop = request.propagation
    # J2 about the true pole needs the epoch; without one the GCRS z axis stands in.
    true_pole = prop.j2_axis == "true_pole" and request.epoch_utc is not None
    return propagate(
        r_start,
        v_start,
        times_s,
        j2=prop.j2,
        method=prop.method,
        step_s=prop.step_s,
        epoch=request.epoch_utc if true_pole else None,
        j2_axis="true_pole" if true_pole else "gcrs_z",
        max_zonal_degree=prop.max_zonal_degree,
    )


def target_states(
    request: OrbitalPlanRequest, times_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The target's GCRS positions and velocities (N, 3) at ``times_s`` (N,), ascending."""
    if request.target.elements is not None:
        return fly(request, *target_start(request)[:2], times_s)
    return _trajectory_states(request.target.states, request, times_s)


def target_start(request: OrbitalPlanRequest) -> tuple[np.ndarray, np.ndarray, OrbitalElements]:
    """The target's GCRS state at the epoch and its osculating elements there."""
    if request.target.elements is not None:
        elements = request.target.elements
        r0, v0 = state_from_elements(elements)
        return r0, v0, elements
    r, v = _trajectory_states(request.target.states, request, np.zeros(1))
    return r[0], v[0], elements_from_state(r[0], v[0])


@dataclass(frozen=True)
class _Flight:
    """Where the target and the camera are at each frame time (GCRS, m, m/s)."""

    times_s: np.ndarray
    r_target_m: np.ndarray
    v_target_m_s: np.ndarray
    q_gcrs_from_body: np.ndarray
    center_m: np.ndarray  # the target's box centre
    r_camera_m: np.ndarray
    v_camera_m_s: np.ndarray
    reference_r_m: np.ndarray  # the state the roll policy's reference comes from
    reference_v_m_s: np.ndarray
    roll_policy: str
    roll_rad: np.ndarray
    interval_names: tuple[str, ...] | None  # None: named from the ranges


def _rssf_flight(request: OrbitalPlanRequest, center_body: np.ndarray) -> _Flight:
    sampler = request.sampler
    r0, v0, _ = target_start(request)
    count = sampler.frame_count
    times = np.zeros(count)
    r_t, v_t = np.tile(r0, (count, 1)), np.tile(v0, (count, 1))
    q_gcrs_from_body = _target_attitude(request, r_t, v_t, times)
    samples = rssf_samples(
        count,
        sampler.intervals,
        np.random.default_rng(sampler.seed),
        sampler.distance_distribution,
    )
    R_gcrs_from_body = matrix_from_quaternion(q_gcrs_from_body)
    center = r_t + R_gcrs_from_body @ center_body
    offset_body = samples.direction * samples.range_m[:, None]
    r_camera = center + np.einsum("nij,nj->ni", R_gcrs_from_body, offset_body)
    # The camera is placed about the target, not flown: it shares the target's velocity, and
    # the roll policy's reference follows the target's orbit.
    return _Flight(
        times, r_t, v_t, q_gcrs_from_body, center, r_camera, v_t, r_t, v_t,
        sampler.camera_roll, samples.roll_rad, tuple(samples.interval),
    )  # fmt: skip


def _sspt_flight(request: OrbitalPlanRequest, center_body: np.ndarray) -> _Flight:
    # From elements (orbit) the target is propagated; from a TLE/OMM (SGP4) or an OEM it
    # follows that trajectory, and the relative modes start from its state at the epoch.
    r0, v0, elements = target_start(request)
    from_elements = request.target.elements is not None
    sampler, observer = request.sampler, request.observer
    motion = observer.motion
    times = _sspt_times(request)
    r_t, v_t = target_states(request, times)
    q_gcrs_from_body = _target_attitude(request, r_t, v_t, times)
    center = r_t + matrix_from_quaternion(q_gcrs_from_body) @ center_body
    if isinstance(motion, Approach):
        # The spiral spans the whole approach, whatever the frames sample of it.
        end = sampler.start_s + (sampler.duration_s or _natural_span_s(request))
        rho, rho_dot = rm.spiral_approach(
            np.append(times, end),
            motion.start_range_m,
            motion.end_range_m,
            mean_motion_rad_s(elements),
            revolutions=motion.revolutions,
            via_ranges_m=motion.via_ranges_m,
        )
        # About the box centre, so the ranges are exactly the spiral's.
        r_obs, v_obs = inertial_from_relative_rtn(center, v_t, rho[:-1], rho_dot[:-1])
    elif isinstance(motion, OwnTrajectory):
        r_obs, v_obs = _trajectory_states(motion.states, request, times)
    else:
        r_obs, v_obs = fly(request, *observer_initial_state(request, r0, v0, elements), times)
        if not from_elements and not isinstance(motion, OwnElements):
            # The natural relative motion comes from both spacecraft flown with the same
            # dynamics from the target's state at the epoch; it is carried, in RTN, onto the
            # target's real (SGP4 / OEM) trajectory, whose own dynamics differ from ours and
            # would otherwise pull the pair apart by kilometres per orbit.
            rho, rho_dot = relative_rtn(*fly(request, r0, v0, times), r_obs, v_obs)
            r_obs, v_obs = inertial_from_relative_rtn(r_t, v_t, rho, rho_dot)
    roll_rad = np.full(len(times), observer.roll_rad)
    return _Flight(
        times, r_t, v_t, q_gcrs_from_body, center, r_obs, v_obs, r_obs, v_obs,
        observer.camera_roll, roll_rad, None,
    )  # fmt: skip


def _orbital_track(
    request: OrbitalPlanRequest, center_body: np.ndarray, chunk_frames: int = PLAN_CHUNK_FRAMES
) -> PoseTrack:
    if isinstance(request.sampler, RssfSampler):
        flight = _rssf_flight(request, center_body)
    else:
        flight = _sspt_flight(request, center_body)
    n = len(flight.times_s)
    if isinstance(chunk_frames, bool) or not isinstance(chunk_frames, int) or chunk_frames < 1:
        raise SatsightError(f"chunk_frames must be a whole number >= 1, got {chunk_frames!r}")
    rates = {name: np.empty((n, 3)) for name in RATE_FIELDS}
    for start in range(0, n, chunk_frames):
        _flight_rates(
            request, center_body, flight, slice(start, min(n, start + chunk_frames)), rates
        )
    keep = request.visibility.on_fail == "keep"
    limits = request.visibility.limits
    columns = {name: np.empty((n, 4)) for name in ("q_cam_from_body", "q_cam_from_gcrs")}
    for name in ("t_cam_from_body_m", "rho_rtn_m", "sun_from_target_cam",
                 "earth_from_target_cam", "moon_from_target_cam"):  # fmt: skip
        columns[name] = np.empty((n, 3))
    for name in (
        "range_m", "phase_angle_rad", "sunlit_fraction", "los_clearance_m",
        "sun_boresight_angle_rad", "sun_distance_m", "earth_distance_m", "moon_distance_m",
    ):  # fmt: skip
        columns[name] = np.empty(n)
    for name in FLAG_FIELDS:
        columns[name] = np.zeros(n, dtype=bool)
    epochs: list[str] = []
    # Every per-frame quantity past the flight is a function of that frame alone: computed a
    # chunk of frames at a time, the plan holds a few arrays per frame and the temporary
    # arrays of one chunk (the Earth's orientation needs ~22 kB a frame while it is computed).
    for start in range(0, n, chunk_frames):
        frames = slice(start, min(n, start + chunk_frames))
        epochs += _plan_chunk(request, flight, frames, columns, limits, keep)
    r_obs, v_obs, times = flight.r_camera_m, flight.v_camera_m_s, flight.times_s
    interval_names = flight.interval_names
    del flight  # the target's states and attitude are no longer needed
    if interval_names is None:
        interval_names = interval_names_for_ranges(
            columns["range_m"], default_intervals(include_hover=True)
        )
    for array in (*columns.values(), *rates.values(), r_obs, v_obs, times):
        if array.flags.owndata:
            array.flags.writeable = False  # handed to the PoseTrack without a copy
    return PoseTrack(
        time_s=times,
        epoch_utc=tuple(epochs),
        interval=interval_names,
        camera_position_gcrs_m=r_obs,
        camera_velocity_gcrs_m_s=v_obs,
        **rates,
        **columns,
    )


def _flight_rates(
    request: OrbitalPlanRequest,
    center_body: np.ndarray,
    flight: _Flight,
    frames: slice,
    rates: dict[str, np.ndarray],
) -> None:
    """Fill ``rates[...][frames]`` (``satsight.poses.pose_rates``): central differences of
    the pose at t -+ RATE_STEP_S, both craft moved along their velocities (the common and
    differential accelerations change the positions by a dt^2 / 2, which cancels in the
    central difference) and the target turned by its attitude law."""
    dt = RATE_STEP_S
    poses = []
    for step in (-dt, dt):
        times = flight.times_s[frames] + step
        r_t = flight.r_target_m[frames] + flight.v_target_m_s[frames] * step
        v_t = flight.v_target_m_s[frames]
        r_obs = flight.r_camera_m[frames] + flight.v_camera_m_s[frames] * step
        q_gcrs_from_body = _target_attitude(request, r_t, v_t, times)
        center = r_t + matrix_from_quaternion(q_gcrs_from_body) @ center_body
        reference, reference_axis = camera_reference(
            flight.roll_policy,
            flight.reference_r_m[frames] + flight.reference_v_m_s[frames] * step,
            flight.reference_v_m_s[frames],
        )
        q_gcrs_from_cam = pointing_gcrs_from_cam(
            r_obs, center, reference, roll_rad=flight.roll_rad[frames],
            reference_axis=reference_axis,
        )  # fmt: skip
        _, t = cam_from_body(q_gcrs_from_cam, q_gcrs_from_body, r_obs, r_t)
        poses.append((q_gcrs_from_cam, q_gcrs_from_body, t))
    (qc0, qb0, t0), (qc1, qb1, t1) = poses
    span = np.full(len(t0), 2.0 * dt)
    rates["omega_cam_rad_s"][frames] = body_rate_rad_s(qc0, qc1, span)
    rates["omega_body_rad_s"][frames] = body_rate_rad_s(qb0, qb1, span)
    rates["t_dot_cam_from_body_m_s"][frames] = (t1 - t0) / (2.0 * dt)


def _plan_chunk(
    request: OrbitalPlanRequest,
    flight: _Flight,
    frames: slice,
    columns: dict[str, np.ndarray],
    limits,
    keep: bool,
) -> list[str]:
    """Fill ``columns[...][frames]`` for one chunk of frames; returns their UTC epochs."""
    times = flight.times_s[frames]
    r_t, v_t = flight.r_target_m[frames], flight.v_target_m_s[frames]
    center, r_obs = flight.center_m[frames], flight.r_camera_m[frames]
    instants = epoch_times(request.epoch_utc, times)
    # The Earth's orientation per frame: the WGS-84 ellipsoid for the inside-the-Earth test,
    # occultation and shadow.
    # (Nutation costs ~70 us an instant; RSSF frames all share one.)
    unique_times, inverse = np.unique(times, return_inverse=True)
    unique_instants = epoch_times(request.epoch_utc, unique_times)
    R_itrs = R_itrs_from_gcrs(unique_instants)[inverse]
    buried = np.flatnonzero(np.atleast_1d(inside_earth(r_obs, R_itrs)))
    if buried.size:
        i = int(buried[0])
        height_m = float(geodetic_height_m((R_itrs[i] @ r_obs[i])[None, :])[0][0])
        raise SatsightError(
            f"frame {frames.start + i} (t = {times[i]:.1f} s) puts the camera inside the Earth "
            f"({-height_m / 1e3:.1f} km below the WGS-84 surface); check the observer's "
            "mode and distances"
        )
    reference, reference_axis = camera_reference(
        flight.roll_policy, flight.reference_r_m[frames], flight.reference_v_m_s[frames]
    )
    q_gcrs_from_cam = pointing_gcrs_from_cam(
        r_obs, center, reference, roll_rad=flight.roll_rad[frames], reference_axis=reference_axis
    )
    columns["q_cam_from_body"][frames], columns["t_cam_from_body_m"][frames] = cam_from_body(
        q_gcrs_from_cam, flight.q_gcrs_from_body[frames], r_obs, r_t
    )
    # The Sun and the Moon at each distinct instant (all RSSF frames share one).
    sun = sun_position_gcrs_m(unique_instants)[inverse]
    moon = moon_position_gcrs_m(unique_instants)[inverse]
    R_cam_from_gcrs = np.swapaxes(matrix_from_quaternion(q_gcrs_from_cam), -1, -2)

    def from_target_cam(body: str, position: np.ndarray) -> None:
        offset = position - center
        distance = np.linalg.norm(offset, axis=1)
        columns[f"{body}_from_target_cam"][frames] = np.einsum(
            "nij,nj->ni", R_cam_from_gcrs, offset / distance[:, None]
        )
        columns[f"{body}_distance_m"][frames] = distance

    from_target_cam("sun", sun)
    from_target_cam("earth", np.zeros_like(center))
    from_target_cam("moon", moon)
    columns["rho_rtn_m"][frames] = np.einsum(
        "nij,nj->ni", rtn_from_inertial(r_t, v_t), r_obs - center
    )
    visibility = assess_visibility(center, r_obs, sun, limits, R_itrs_from_gcrs=R_itrs)
    if not keep:
        for name in FLAG_FIELDS:
            columns[name][frames] = np.asarray(getattr(visibility, name), dtype=bool)
    columns["range_m"][frames] = np.linalg.norm(r_obs - center, axis=1)
    for name in ("phase_angle_rad", "sunlit_fraction", "los_clearance_m"):
        columns[name][frames] = np.asarray(getattr(visibility, name))
    columns["sun_boresight_angle_rad"][frames] = np.asarray(visibility.sun_boresight_angle_rad)
    columns["q_cam_from_gcrs"][frames] = quaternion_conjugate(q_gcrs_from_cam)
    epochs = format_epoch_utc(instants, places=3)
    return list(epochs) if isinstance(epochs, list) else [epochs]
