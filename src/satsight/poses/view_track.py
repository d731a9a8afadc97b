"""The pose track of views given in the body frame (``frames:``).

Each frame places the camera by distance, azimuth, elevation and roll about the target's
bounding-box centre (``satsight.poses.views``), or by a given camera pose; the Sun, the Earth
and the Moon are placed by hand in the body frame. No orbit, so no RTN position, no sky and
no visibility tests: every frame is at the epoch, in full Sun, and visible.
"""

from __future__ import annotations

import numpy as np

from satsight.frames.rigid import RigidTransform
from satsight.poses.distance_intervals import default_intervals, interval_name_for_range
from satsight.poses.plan_request import ViewsPlanRequest
from satsight.poses.track import PoseTrack
from satsight.vectors import angle_between_rad


def views_track(request: ViewsPlanRequest, center: np.ndarray) -> PoseTrack:
    """The track of ``request``'s views about the target's box centre ``center`` (3,),
    body frame, m."""
    n = len(request.frames)
    poses = [
        frame if isinstance(frame, RigidTransform) else frame.cam_from_body(center)
        for frame in request.frames
    ]
    R = np.stack([p.R_a_from_b for p in poses])
    sun_body = request.sun_direction_body
    sun_cam = R @ sun_body
    nan3 = np.full((n, 3), np.nan)
    nan = np.full(n, np.nan)

    def body_in_cam(vector: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        if vector is None:
            return nan3, nan
        return R @ (vector / np.linalg.norm(vector)), np.full(n, np.linalg.norm(vector))

    earth_dir, earth_dist = body_in_cam(request.earth_center_from_target_m)
    moon_dir, moon_dist = body_in_cam(request.moon_center_from_target_m)
    center_cam = np.einsum("nij,j->ni", R, center) + np.stack([p.t_a_from_b_m for p in poses])
    range_m = np.linalg.norm(center_cam, axis=1)
    boresight = np.tile([0.0, 0.0, 1.0], (n, 1))
    no = np.zeros(n, dtype=bool)
    intervals = default_intervals(include_hover=True)
    return PoseTrack(
        time_s=np.zeros(n),
        epoch_utc=("",) * n,
        q_cam_from_body=np.stack([p.q_a_from_b for p in poses]),
        t_cam_from_body_m=np.stack([p.t_a_from_b_m for p in poses]),
        sun_from_target_cam=sun_cam,
        sun_distance_m=np.full(n, request.sun_distance_m),
        earth_from_target_cam=earth_dir,
        earth_distance_m=earth_dist,
        moon_from_target_cam=moon_dir,
        moon_distance_m=moon_dist,
        rho_rtn_m=nan3,
        range_m=range_m,
        phase_angle_rad=angle_between_rad(sun_cam, -center_cam),
        sunlit_fraction=np.ones(n),
        los_clearance_m=np.full(n, np.inf),
        sun_boresight_angle_rad=angle_between_rad(sun_cam, boresight),
        earth_occulted=no,
        eclipsed=no,
        sun_excluded=no,
        phase_rejected=no,
        interval=tuple(interval_name_for_range(r, intervals) for r in range_m),
        q_cam_from_gcrs=np.full((n, 4), np.nan),
        camera_position_gcrs_m=nan3,
        camera_velocity_gcrs_m_s=nan3,
    )
