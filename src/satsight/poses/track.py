"""The frame plan: where the camera, the Sun, the Earth and the Moon are at every frame.

A ``PoseTrack`` is what the geometric half of satsight hands to the renderer. It holds one
row per frame, every array with the frame on its first axis:

- ``time_s`` (N,): seconds after the scenario epoch; ``epoch_utc`` (N,): the same instant as
  a UTC ISO string ("" when the scenario has no epoch).
- ``q_cam_from_body`` (N, 4), scalar first, and ``t_cam_from_body_m`` (N, 3):
  ``x_cam = R(q_cam_from_body) @ x_body + t_cam_from_body_m``.
- ``sun_from_target_cam`` (N, 3), ``earth_from_target_cam`` (N, 3),
  ``moon_from_target_cam`` (N, 3): unit vectors from the target towards each body's
  centre, in camera axes; ``sun_distance_m``, ``earth_distance_m``, ``moon_distance_m``
  (N,): the distances from the target to those centres (NaN where a body is not modelled).
- ``rho_rtn_m`` (N, 3): the camera relative to the target's bounding-box centre, in the
  target's RTN frame (NaN without an orbit).
- ``range_m`` (N,): camera to the target's bounding-box centre.
- ``phase_angle_rad`` (N,): Sun-target-camera angle at the box centre.
- ``sunlit_fraction`` (N,): the fraction of the solar disc seen from the target (1 in full
  Sun, 0 in the umbra).
- ``los_clearance_m`` (N,): how far the camera-target line of sight passes above the
  Earth's surface (negative: through the Earth; +inf without an orbit).
- ``sun_boresight_angle_rad`` (N,): angle between the boresight and the Sun.
- flags (N,) bool: ``earth_occulted``, ``eclipsed``, ``sun_excluded``, ``phase_rejected``,
  and ``visible`` (none of the four).
- ``interval`` (N,): the name of the distance interval a frame belongs to.
- ``q_cam_from_gcrs`` (N, 4): the camera's attitude in the inertial frame (GCRS axes, which
  are the ICRS axes), scalar first; ``camera_position_gcrs_m`` (N, 3) and
  ``camera_velocity_gcrs_m_s`` (N, 3): the camera's geocentric state. All NaN for views
  given in the body frame (no orbit, so no sky).
- ``omega_cam_rad_s`` (N, 3): the camera's inertial angular velocity in camera axes;
  ``omega_body_rad_s`` (N, 3): the target's inertial angular velocity in body axes;
  ``t_dot_cam_from_body_m_s`` (N, 3): the rate of ``t_cam_from_body_m`` (the body origin's
  velocity seen in the turning camera frame). Central differences of the plan at t +- 0.05 s
  (``satsight.poses.pose_rates``); zero for views given in the body frame (no motion).

The pose convention is the one of the dataset labels (docs/conventions.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.frames.quaternion import canonical_quaternion, matrix_from_quaternion
from satsight.frames.rigid import RigidTransform

_VECTOR_FIELDS = (
    "t_cam_from_body_m",
    "sun_from_target_cam",
    "earth_from_target_cam",
    "moon_from_target_cam",
    "rho_rtn_m",
    "camera_position_gcrs_m",
    "camera_velocity_gcrs_m_s",
)
RATE_FIELDS = ("omega_cam_rad_s", "omega_body_rad_s", "t_dot_cam_from_body_m_s")
_SCALAR_FIELDS = (
    "time_s",
    "sun_distance_m",
    "earth_distance_m",
    "moon_distance_m",
    "range_m",
    "phase_angle_rad",
    "sunlit_fraction",
    "los_clearance_m",
    "sun_boresight_angle_rad",
)
FLAG_FIELDS = ("earth_occulted", "eclipsed", "sun_excluded", "phase_rejected")


@dataclass(frozen=True)
class PoseTrack:
    """Per-frame geometry of a scenario (see the module docstring for every field)."""

    time_s: np.ndarray
    epoch_utc: tuple[str, ...]
    q_cam_from_body: np.ndarray
    t_cam_from_body_m: np.ndarray
    sun_from_target_cam: np.ndarray
    sun_distance_m: np.ndarray
    earth_from_target_cam: np.ndarray
    earth_distance_m: np.ndarray
    moon_from_target_cam: np.ndarray
    moon_distance_m: np.ndarray
    rho_rtn_m: np.ndarray
    range_m: np.ndarray
    phase_angle_rad: np.ndarray
    sunlit_fraction: np.ndarray
    los_clearance_m: np.ndarray
    sun_boresight_angle_rad: np.ndarray
    earth_occulted: np.ndarray
    eclipsed: np.ndarray
    sun_excluded: np.ndarray
    phase_rejected: np.ndarray
    interval: tuple[str, ...]
    q_cam_from_gcrs: np.ndarray
    camera_position_gcrs_m: np.ndarray
    camera_velocity_gcrs_m_s: np.ndarray
    omega_cam_rad_s: np.ndarray | None = None
    omega_body_rad_s: np.ndarray | None = None
    t_dot_cam_from_body_m_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = np.shape(self.time_s)[0] if np.ndim(self.time_s) == 1 else -1
        if n < 0:
            raise SatsightError(f"time_s must be 1-D, got shape {np.shape(self.time_s)}")

        def check(name: str, shape: tuple[int, ...], dtype: type) -> None:
            value = np.asarray(getattr(self, name), dtype=dtype)
            if value.shape != shape:
                raise SatsightError(f"PoseTrack.{name} must have shape {shape}, got {value.shape}")
            # A read-only array that owns its memory is kept as it is (the planner hands over
            # its freshly built columns so); any other is copied, so the caller's later
            # writes cannot reach the track.
            if value.flags.writeable or not value.flags.owndata:
                value = value.copy()
                value.flags.writeable = False
            object.__setattr__(self, name, value)

        for name in ("q_cam_from_body", "q_cam_from_gcrs"):
            check(name, (n, 4), np.float64)
            rows = np.all(np.isfinite(getattr(self, name)), axis=1)
            if rows.any():
                q = getattr(self, name).copy()
                q[rows] = canonical_quaternion(q[rows])
                q.flags.writeable = False
                object.__setattr__(self, name, q)
        if not np.all(np.isfinite(self.q_cam_from_body)):
            raise SatsightError("PoseTrack.q_cam_from_body must be finite in every frame")
        for name in RATE_FIELDS:
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros((n, 3)))
        for name in (*_VECTOR_FIELDS, *RATE_FIELDS):
            check(name, (n, 3), np.float64)
        for name in RATE_FIELDS:
            if not np.all(np.isfinite(getattr(self, name))):
                raise SatsightError(f"PoseTrack.{name} must be finite in every frame")
        for name in _SCALAR_FIELDS:
            check(name, (n,), np.float64)
        for name in FLAG_FIELDS:
            check(name, (n,), bool)
        for name in ("epoch_utc", "interval"):
            value = tuple(str(v) for v in getattr(self, name))
            if len(value) != n:
                raise SatsightError(f"PoseTrack.{name} must have {n} entries, got {len(value)}")
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    @property
    def visible(self) -> np.ndarray:
        """(N,) bool: the frames that pass every visibility test."""
        flags = np.stack([getattr(self, name) for name in FLAG_FIELDS])
        return ~flags.any(axis=0)

    def cam_from_body(self, index: int) -> RigidTransform:
        """The camera pose of frame ``index``."""
        return RigidTransform.from_quaternion(
            self.q_cam_from_body[index], self.t_cam_from_body_m[index]
        )

    @property
    def has_sky(self) -> bool:
        """Whether the camera's inertial attitude is known (frames planned from orbits)."""
        return bool(len(self)) and bool(np.all(np.isfinite(self.q_cam_from_gcrs)))

    def R_cam_from_gcrs(self, index: int) -> np.ndarray:
        """(3, 3) rotation from GCRS axes to the camera frame of frame ``index``."""
        if not np.all(np.isfinite(self.q_cam_from_gcrs[index])):
            raise SatsightError(
                "this frame plan has no inertial camera attitude (views given in the body "
                "frame); plan frames from orbits to place the sky"
            )
        return matrix_from_quaternion(self.q_cam_from_gcrs[index])

    def select(self, keep: np.ndarray) -> PoseTrack:
        """The frames where ``keep`` (N,) bool is true, or those at integer indices."""
        index = np.asarray(keep)
        if index.dtype == bool:
            if index.shape != (len(self),):
                raise SatsightError(f"the frame mask must have shape ({len(self)},)")
            index = np.flatnonzero(index)
        values = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, tuple):
                values[field.name] = tuple(value[i] for i in index)
            else:
                values[field.name] = value[index]
        return PoseTrack(**values)

    def record(self, index: int) -> dict:
        """Frame ``index`` as a JSON-ready dict (angles in degrees, NaN and inf as None)."""

        def number(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        def vector(v: np.ndarray) -> list[float] | None:
            return [float(c) for c in v] if np.all(np.isfinite(v)) else None

        i = index
        return {
            "time_s": float(self.time_s[i]),
            "epoch_utc": self.epoch_utc[i] or None,
            "interval": self.interval[i],
            "range_m": float(self.range_m[i]),
            "rho_rtn_m": vector(self.rho_rtn_m[i]),
            "sun_from_target_cam": vector(self.sun_from_target_cam[i]),
            "sun_distance_m": number(self.sun_distance_m[i]),
            "earth_from_target_cam": vector(self.earth_from_target_cam[i]),
            "earth_distance_m": number(self.earth_distance_m[i]),
            "moon_from_target_cam": vector(self.moon_from_target_cam[i]),
            "moon_distance_m": number(self.moon_distance_m[i]),
            "phase_angle_deg": float(np.degrees(self.phase_angle_rad[i])),
            "sunlit_fraction": float(self.sunlit_fraction[i]),
            "los_clearance_m": number(self.los_clearance_m[i]),
            "sun_boresight_angle_deg": float(np.degrees(self.sun_boresight_angle_rad[i])),
            "earth_occulted": bool(self.earth_occulted[i]),
            "eclipsed": bool(self.eclipsed[i]),
            "sun_excluded": bool(self.sun_excluded[i]),
            "phase_rejected": bool(self.phase_rejected[i]),
            "visible": bool(self.visible[i]),
            "q_cam_from_gcrs": vector(self.q_cam_from_gcrs[i]),
            "camera_position_gcrs_m": vector(self.camera_position_gcrs_m[i]),
            "camera_velocity_gcrs_m_s": vector(self.camera_velocity_gcrs_m_s[i]),
            "omega_cam_rad_s": vector(self.omega_cam_rad_s[i]),
            "omega_body_rad_s": vector(self.omega_body_rad_s[i]),
            "t_dot_cam_from_body_m_s": vector(self.t_dot_cam_from_body_m_s[i]),
        }
