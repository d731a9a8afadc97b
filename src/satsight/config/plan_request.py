"""The scenario's orbital keys turned into what the frame plan is asked for
(``satsight.poses.plan_request``): typed, in SI units; and the size check of an SSPT plan.

Non-SI units of the keys (``radius_km``, ``phase_deg``, ``rate_body_deg_s``) are converted
here and nowhere else.
"""

from __future__ import annotations

import math

import numpy as np

from satsight.config.orbital import (
    MAX_FRAMES,
    MAX_SPAN_S,
    ApproachConfig,
    AttitudeConfig,
    FlyAroundConfig,
    FlyByConfig,
    HoverConfig,
    ObserverConfig,
    ObserverElementsConfig,
    OemObserverConfig,
    OmmObserverConfig,
    OrbitConfig,
    PropagationConfig,
    RelativeRtnConfig,
    RssfConfig,
    SamplerConfig,
    SsptConfig,
    TleObserverConfig,
    TrajectoryConfig,
    VisibilityConfig,
)
from satsight.ephemeris.orbits import orbital_period_s
from satsight.errors import SatsightError
from satsight.poses.distance_intervals import DistanceInterval
from satsight.poses.plan_request import (
    Approach,
    FlyAround,
    FlyBy,
    Hover,
    Observer,
    ObserverMotion,
    OrbitalPlanRequest,
    OwnElements,
    OwnTrajectory,
    Propagation,
    RelativeRtn,
    RssfSampler,
    SsptSampler,
    TargetTrajectory,
    VisibilityRule,
    natural_span_s,
)


def observer_motion(observer: ObserverConfig) -> ObserverMotion:
    """The observer's motion of an ``observer:`` section, in SI units."""
    if isinstance(observer, FlyAroundConfig):
        return FlyAround(
            radius_m=observer.radius_km * 1e3, phase_rad=math.radians(observer.phase_deg)
        )
    if isinstance(observer, FlyByConfig):
        return FlyBy(
            miss_distance_m=observer.miss_distance_km * 1e3,
            start_along_track_m=observer.start_along_track_km * 1e3,
        )
    if isinstance(observer, ApproachConfig):
        return Approach(
            start_range_m=observer.start_range_km * 1e3,
            end_range_m=observer.end_range_km * 1e3,
            revolutions=observer.revolutions,
            via_ranges_m=observer.via_ranges_m(),
        )
    if isinstance(observer, HoverConfig):
        return Hover(range_m=observer.range_km * 1e3, side=observer.side)
    if isinstance(observer, ObserverElementsConfig):
        return OwnElements(elements=observer.orbit.build())
    if isinstance(observer, RelativeRtnConfig):
        return RelativeRtn(
            position_rtn_m=np.asarray(observer.position_rtn_km, dtype=np.float64) * 1e3,
            velocity_rtn_m_s=np.asarray(observer.velocity_rtn_m_s, dtype=np.float64),
        )
    if isinstance(observer, TleObserverConfig | OmmObserverConfig | OemObserverConfig):
        return OwnTrajectory(states=observer.load())
    raise SatsightError(f"observer mode {observer.mode!r} has no motion")


def target_trajectory(trajectory: TrajectoryConfig) -> TargetTrajectory:
    """The target's trajectory of an ``orbit``, ``tle``, ``omm`` or ``oem`` section."""
    semi_major_axis_m = trajectory.semi_major_axis_km * 1e3
    if isinstance(trajectory, OrbitConfig):
        return TargetTrajectory(semi_major_axis_m, elements=trajectory.build())
    return TargetTrajectory(semi_major_axis_m, states=trajectory.load())


def _sampler(sampler: SamplerConfig) -> SsptSampler | RssfSampler:
    if isinstance(sampler, SsptConfig):
        return SsptSampler(
            start_s=sampler.start_s,
            duration_s=sampler.duration_s,
            frame_count=sampler.frame_count,
            step_s=sampler.step_s,
            step_deg=sampler.step_deg,
        )
    return RssfSampler(
        frame_count=sampler.frame_count,
        seed=sampler.seed,
        intervals=_rssf_intervals(sampler),
        distance_distribution=sampler.distance_distribution,
        camera_roll=sampler.camera_roll,
    )


def _rssf_intervals(sampler: RssfConfig) -> tuple[DistanceInterval, ...]:
    intervals = [
        DistanceInterval(far_m=far * 1e3, near_m=near * 1e3, name=f"{far:g}-{near:g} km")
        for far, near in sampler.intervals_km
    ]
    if sampler.include_hover:
        hover = sampler.hover_range_km * 1e3
        intervals.append(
            DistanceInterval(far_m=hover, near_m=hover, name=f"hover {sampler.hover_range_km:g} km")
        )
    return tuple(intervals)


def orbital_plan_request(
    epoch_utc: str | None,
    trajectory: TrajectoryConfig,
    attitude: AttitudeConfig,
    sampler: SamplerConfig,
    observer: ObserverConfig | None,
    visibility: VisibilityConfig,
    propagation: PropagationConfig,
) -> OrbitalPlanRequest:
    """The plan request of frames planned from orbits, from the scenario's sections."""
    return OrbitalPlanRequest(
        epoch_utc=epoch_utc,
        target=target_trajectory(trajectory),
        attitude=attitude.build(),
        sampler=_sampler(sampler),
        observer=None
        if observer is None
        else Observer(
            motion=observer_motion(observer),
            camera_roll=observer.camera_roll,
            roll_rad=math.radians(observer.roll_deg),
        ),
        visibility=VisibilityRule(limits=visibility.limits(), on_fail=visibility.on_fail),
        propagation=Propagation(
            method=propagation.method,
            step_s=propagation.step_s,
            j2=propagation.j2,
            j2_axis=propagation.j2_axis,
            max_zonal_degree=propagation.max_zonal_degree,
        ),
    )


def check_sspt_size(orbit: TrajectoryConfig, observer: ObserverConfig, sampler: SsptConfig) -> None:
    """Refuse SSPT plans longer than MAX_SPAN_S or with more than MAX_FRAMES frames."""
    span = sampler.duration_s or natural_span_s(
        orbit.semi_major_axis_km * 1e3, observer_motion(observer)
    )
    if sampler.start_s + span > MAX_SPAN_S:
        raise ValueError(
            f"the SSPT span ends {sampler.start_s + span:.4g} s after the epoch, beyond the "
            f"{MAX_SPAN_S:.0f} s (366 days) allowed; set sampler.duration_s"
            + (
                " (a fly-by's default span is its whole pass, which a small miss distance "
                "makes long)"
                if observer.mode == "fly_by" and sampler.duration_s is None
                else ""
            )
        )
    if sampler.step_s is not None:
        count = span / sampler.step_s + 1
    elif sampler.step_deg is not None:
        count = 360.0 * span / orbital_period_s(orbit.semi_major_axis_km * 1e3) / sampler.step_deg
    else:
        count = sampler.frame_count
    if count > MAX_FRAMES:
        raise ValueError(
            f"the sampler would plan {count:.4g} frames, more than {MAX_FRAMES}; use a larger "
            "step or a shorter duration_s"
        )
