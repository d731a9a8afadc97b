"""Can the camera see the target, and is the target in sunlight? Per-frame summary.

Frame and units: every position is a geocentric **GCRS** vector in metres (the frame of
:mod:`satsight.ephemeris.sun_moon` and :mod:`satsight.ephemeris.orbits`), angles in rad.
Vector arguments have shape (3,) or (N, 3) (components on the last axis, float64); a (3,)
argument is broadcast against (N, 3) ones. The angle functions return a Python scalar when
every vector argument is (3,), else an (N,) array; :func:`assess_visibility` always returns
(N,) arrays.

The stages live in their own modules: :mod:`satsight.ephemeris.occultation` (the line of
sight and the Earth, the camera inside the Earth), :mod:`satsight.ephemeris.shadow`
(cylindrical and conical shadow, beta angle, eclipse durations) and
:mod:`satsight.ephemeris.wgs84` (the Earth's ellipsoid). Here: the viewing angles, the
thresholds (:class:`VisibilityLimits`) and the per-frame verdict (:func:`assess_visibility`).

The Earth is the WGS-84 ellipsoid when the Earth's orientation ``R_itrs_from_gcrs`` is
given, else the sphere of radius a (6378137 m), which stands 21.4 km above the ellipsoid at
the poles (see the two modules for what that costs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from satsight.ephemeris.geometry import finish, positive_length, require_nonzero, stack
from satsight.ephemeris.occultation import DEFAULT_ATMOSPHERE_MARGIN_M, los_clearance_m
from satsight.ephemeris.shadow import sunlit_fraction
from satsight.errors import SatsightError
from satsight.vectors import angle_between_rad

# A frame counts as eclipsed when sunlit_fraction < min_sunlit_fraction - this tolerance,
# so that exactly 1.0 (full Sun) passes min_sunlit_fraction = 1 and a rounding-level dip in
# the first or last instant of a penumbra does not flip a flag. Dimensionless (a fraction
# of the solar flux).
SUNLIT_FRACTION_TOLERANCE = 1e-9


# --- angles --------------------------------------------------------------------------------


def phase_angle_rad(
    target_m: ArrayLike, observer_m: ArrayLike, sun_m: ArrayLike
) -> float | np.ndarray:
    """Sun-target-observer angle, rad in [0, pi], at the target.

    target_m, observer_m, sun_m: GCRS positions, m, (3,) or (N, 3). The angle between the
    directions target -> Sun and target -> observer: 0 when the observer has the Sun behind
    it (it sees the fully lit face), pi when it looks at the target against the Sun.
    """
    (t, o, s), _, single = stack(target_m=target_m, observer_m=observer_m, sun_m=sun_m)
    to_sun, to_observer = s - t, o - t
    require_nonzero(to_sun, "sun_m - target_m")
    require_nonzero(to_observer, "observer_m - target_m")
    return finish(angle_between_rad(to_sun, to_observer), single)


def sun_boresight_angle_rad(
    observer_m: ArrayLike, target_m: ArrayLike, sun_m: ArrayLike
) -> float | np.ndarray:
    """Angle at the observer between the boresight and the Sun, rad in [0, pi].

    observer_m, target_m, sun_m: GCRS positions, m, (3,) or (N, 3). The angle between the
    directions observer -> target (the camera's boresight) and observer -> Sun's centre:
    0 when the camera looks straight at the Sun.
    """
    (o, t, s), _, single = stack(observer_m=observer_m, target_m=target_m, sun_m=sun_m)
    boresight, to_sun = t - o, s - o
    require_nonzero(boresight, "target_m - observer_m")
    require_nonzero(to_sun, "sun_m - observer_m")
    return finish(angle_between_rad(boresight, to_sun), single)


# --- per-frame summary ---------------------------------------------------------------------


@dataclass(frozen=True)
class VisibilityLimits:
    """Thresholds that decide whether a frame is usable.

    atmosphere_margin_m >= 0: the camera-target line of sight must pass at least this high
    above the Earth's surface, m (default 100 km, the Kármán line: below it the line crosses
    the atmosphere, which scatters and absorbs; flag ``earth_occulted``).

    min_sunlit_fraction in [0, 1]: a frame is ``eclipsed`` when the target's
    :func:`sunlit_fraction` is below this (less SUNLIT_FRACTION_TOLERANCE). Default 1: any
    frame in the penumbra is rejected, since the irradiance there falls from full to zero
    within seconds and the flux then also depends on limb darkening and the atmosphere,
    which the model leaves out. 0 disables the test.

    sun_exclusion_rad in [0, pi]: a frame is ``sun_excluded`` when the Sun's centre is
    closer than this to the boresight. Default 30 deg, a typical Sun exclusion half-angle of
    a baffled visible camera or star tracker: nearer to the Sun, stray light floods the
    detector.

    min_phase_angle_rad <= max_phase_angle_rad, both in [0, pi]: a frame is
    ``phase_rejected`` outside this range of the Sun-target-camera angle. Defaults 0 and
    150 deg: beyond 150 deg a sphere shows the camera less than (1 + cos 150 deg) / 2 = 7 %
    of its lit face, a thin crescent. For a Sun much farther than the camera-target range,
    phase angle = pi - sun_boresight_angle (up to the range / Sun-distance parallax), so
    with the defaults the two tests reject the same frames; each is kept so that either can
    be loosened alone.
    """

    atmosphere_margin_m: float = DEFAULT_ATMOSPHERE_MARGIN_M
    min_sunlit_fraction: float = 1.0
    sun_exclusion_rad: float = math.radians(30.0)
    min_phase_angle_rad: float = 0.0
    max_phase_angle_rad: float = math.radians(150.0)

    def __post_init__(self) -> None:
        for name in (
            "atmosphere_margin_m",
            "min_sunlit_fraction",
            "sun_exclusion_rad",
            "min_phase_angle_rad",
            "max_phase_angle_rad",
        ):
            value = getattr(self, name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not math.isfinite(number):
                raise SatsightError(f"VisibilityLimits.{name} must be a finite number; got {value}")
            object.__setattr__(self, name, number)
        if self.atmosphere_margin_m < 0.0:
            raise SatsightError(
                "VisibilityLimits.atmosphere_margin_m must be >= 0 m (how high above the "
                f"surface the line of sight must pass); got {self.atmosphere_margin_m} m"
            )
        if not 0.0 <= self.min_sunlit_fraction <= 1.0:
            raise SatsightError(
                "VisibilityLimits.min_sunlit_fraction must lie in [0, 1] (1: full Sun only, "
                f"0: never reject for shadow); got {self.min_sunlit_fraction}"
            )
        for name in ("sun_exclusion_rad", "min_phase_angle_rad", "max_phase_angle_rad"):
            value = getattr(self, name)
            if not 0.0 <= value <= math.pi:
                raise SatsightError(
                    f"VisibilityLimits.{name} must lie in [0, pi] rad; got {value} rad "
                    f"({math.degrees(value)} deg); give angles in radians"
                )
        if self.min_phase_angle_rad > self.max_phase_angle_rad:
            raise SatsightError(
                "VisibilityLimits.min_phase_angle_rad must not exceed max_phase_angle_rad; got "
                f"{self.min_phase_angle_rad} > {self.max_phase_angle_rad} rad"
            )


@dataclass(frozen=True)
class FrameVisibility:
    """Per-frame visibility geometry and flags; every field is a read-only (N,) array.

    los_clearance_m: lowest altitude of the camera-target segment above the Earth's
    surface (geodetic height over the WGS-84 ellipsoid, or height above the sphere of
    radius a without the Earth's orientation), m. sunlit_fraction: :func:`sunlit_fraction`
    at the target. sun_boresight_angle_rad: boresight-Sun angle at the camera.
    phase_angle_rad: Sun-target-camera angle.
    earth_occulted, eclipsed, sun_excluded, phase_rejected: bool flags from
    :class:`VisibilityLimits`.
    """

    los_clearance_m: np.ndarray
    sunlit_fraction: np.ndarray
    sun_boresight_angle_rad: np.ndarray
    phase_angle_rad: np.ndarray
    earth_occulted: np.ndarray
    eclipsed: np.ndarray
    sun_excluded: np.ndarray
    phase_rejected: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in (
            ("los_clearance_m", np.float64),
            ("sunlit_fraction", np.float64),
            ("sun_boresight_angle_rad", np.float64),
            ("phase_angle_rad", np.float64),
            ("earth_occulted", bool),
            ("eclipsed", bool),
            ("sun_excluded", bool),
            ("phase_rejected", bool),
        ):
            value = np.array(getattr(self, name), dtype=dtype).reshape(-1)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        n = self.los_clearance_m.shape[0]
        if any(getattr(self, f).shape[0] != n for f in self.__dataclass_fields__):
            raise SatsightError("FrameVisibility fields must all have the same length N")

    @property
    def visible(self) -> np.ndarray:
        """(N,) bool: frames with none of the four flags set."""
        return ~(self.earth_occulted | self.eclipsed | self.sun_excluded | self.phase_rejected)


def assess_visibility(
    target_m: ArrayLike,
    observer_m: ArrayLike,
    sun_m: ArrayLike,
    limits: VisibilityLimits | None = None,
    R_itrs_from_gcrs: ArrayLike | None = None,
    earth_sphere_radius_m: float | None = None,
) -> FrameVisibility:
    """Visibility geometry and flags of N frames.

    target_m, observer_m (the camera), sun_m (the Sun's geocentric position): GCRS, m, (3,)
    or (N, 3); all (3,) gives N = 1. limits: thresholds (default ``VisibilityLimits()``).
    R_itrs_from_gcrs: the Earth's orientation at each frame, (3, 3) or (N, 3, 3) with
    ``x_itrs = R_itrs_from_gcrs @ x_gcrs``; given, the Earth is the WGS-84 ellipsoid for the
    line of sight and the shadow; None, the sphere of radius a. earth_sphere_radius_m: the
    Earth as a sphere of this radius, m, for the line of sight and the shadow, whatever
    R_itrs_from_gcrs says (a scenario's ``earth.shape: sphere`` draws the mean sphere
    R1 = 6 371 008.8 m; passing it keeps the shadow and the occultation on the drawn Earth).
    Flags: earth_occulted where los_clearance_m < atmosphere_margin_m; eclipsed where
    sunlit_fraction < min_sunlit_fraction - SUNLIT_FRACTION_TOLERANCE; sun_excluded where
    sun_boresight_angle_rad < sun_exclusion_rad; phase_rejected where the phase angle is
    outside [min_phase_angle_rad, max_phase_angle_rad]. The Sun exclusion does not ask
    whether the Earth hides the Sun from the camera (it errs on the side of rejecting).
    """
    limits = VisibilityLimits() if limits is None else limits
    if not isinstance(limits, VisibilityLimits):
        raise SatsightError(
            f"limits must be a VisibilityLimits (or None for the defaults); got {type(limits)}"
        )
    (target, observer, sun), R, _ = stack(
        R_itrs_from_gcrs, target_m=target_m, observer_m=observer_m, sun_m=sun_m
    )
    if earth_sphere_radius_m is None:
        clearance = np.asarray(los_clearance_m(observer, target, R_itrs_from_gcrs=R))
        fraction = np.asarray(sunlit_fraction(target, sun, R_itrs_from_gcrs=R))
    else:
        radius = positive_length(earth_sphere_radius_m, "earth_sphere_radius_m")
        clearance = np.asarray(los_clearance_m(observer, target, body_radius_m=radius))
        fraction = np.asarray(sunlit_fraction(target, sun, earth_radius_m=radius))
    boresight = np.asarray(sun_boresight_angle_rad(observer, target, sun))
    phase = np.asarray(phase_angle_rad(target, observer, sun))
    return FrameVisibility(
        los_clearance_m=clearance,
        sunlit_fraction=fraction,
        sun_boresight_angle_rad=boresight,
        phase_angle_rad=phase,
        earth_occulted=clearance < limits.atmosphere_margin_m,
        eclipsed=fraction < limits.min_sunlit_fraction - SUNLIT_FRACTION_TOLERANCE,
        sun_excluded=boresight < limits.sun_exclusion_rad,
        phase_rejected=(phase < limits.min_phase_angle_rad) | (phase > limits.max_phase_angle_rad),
    )
