"""Scenario keys for frames planned from orbits: the target's orbit and attitude, the
observer's operational mode, the viewpoint sampler, and the visibility limits.

Non-SI units appear only here, in the key's name (``semi_major_axis_km``, ``radius_km``,
``rate_body_deg_s``); ``satsight.config.plan_request`` converts them to SI for the
frame plan.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M
from satsight.ephemeris.oem import read_oem
from satsight.ephemeris.oem_ephemeris import OemEphemeris
from satsight.ephemeris.orbits import MU_EARTH_M3_S2, OrbitalElements
from satsight.ephemeris.sgp4_orbit import Sgp4Orbit
from satsight.ephemeris.tle import parse_tle, read_omm_file, read_tle_file, select_orbit
from satsight.ephemeris.visibility import DEFAULT_ATMOSPHERE_MARGIN_M, VisibilityLimits
from satsight.poses.attitude import ROLL_POLICIES
from satsight.poses.distance_intervals import APPROACH_INTERVALS_KM, HOVER_DISTANCE_KM
from satsight.poses.plan_request import AttitudeLaw

# Lowest perigee accepted: below ~100 km an orbit decays within hours.
MIN_PERIGEE_ALTITUDE_KM = 100.0
# Largest distance between observer and target a mode may set up, km (the camera models a
# close-range inspector; 1000 km is ten times the paper's hover distance).
MAX_RELATIVE_KM = 1000.0
# Longest SSPT span and most frames a plan may hold.
MAX_SPAN_S = 366 * 86400.0
MAX_FRAMES = 1_000_000


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Vector3 = tuple[float, float, float]


class OrbitConfig(_Strict):
    """Osculating classical elements at the scenario epoch, GCRS (km and degrees)."""

    semi_major_axis_km: float = Field(gt=0)
    eccentricity: float = Field(default=0.0, ge=0, lt=1)
    inclination_deg: float = Field(default=0.0, ge=0, le=180)
    raan_deg: float = 0.0
    arg_perigee_deg: float = 0.0
    true_anomaly_deg: float = 0.0

    @model_validator(mode="after")
    def _above_ground(self) -> OrbitConfig:
        perigee_km = self.semi_major_axis_km * (1.0 - self.eccentricity)
        floor_km = EARTH_EQUATORIAL_RADIUS_M / 1e3 + MIN_PERIGEE_ALTITUDE_KM
        if perigee_km < floor_km:
            raise ValueError(
                f"the perigee radius a (1 - e) = {perigee_km:.1f} km is below {floor_km:.1f} km "
                f"(the Earth's equatorial radius plus {MIN_PERIGEE_ALTITUDE_KM:g} km); "
                "semi_major_axis_km is measured from the Earth's centre, not the surface"
            )
        return self

    def build(self) -> OrbitalElements:
        return OrbitalElements.from_km_deg(
            self.semi_major_axis_km,
            self.eccentricity,
            self.inclination_deg,
            self.raan_deg,
            self.arg_perigee_deg,
            self.true_anomaly_deg,
        )


def _unit_quaternion(q: tuple[float, float, float, float], name: str) -> np.ndarray:
    array = np.asarray(q, dtype=np.float64)
    norm = float(np.linalg.norm(array))
    if not norm > 1e-9:
        raise ValueError(f"{name} must be a non-zero quaternion [qw, qx, qy, qz]")
    if abs(norm - 1.0) > 1e-3:
        raise ValueError(
            f"{name} must be a unit quaternion [qw, qx, qy, qz] (norm 1 to 1e-3); its norm is "
            f"{norm:.6g}"
        )
    return array / norm


class AttitudeConfig(_Strict):
    """How the target's body frame turns.

    ``lvlh_fixed``: three-axis stabilised in its local orbital frame (LVLH, CCSDS) with the
    fixed offset ``q_ref_from_body`` = q_lvlh_from_body. ``inertial``: fixed in GCRS,
    ``q_ref_from_body`` = q_gcrs_from_body. ``spinning``: starts at ``q_ref_from_body`` =
    q_gcrs_from_body at the epoch and turns at the constant body-frame rate
    ``rate_body_deg_s``.
    """

    law: Literal["lvlh_fixed", "inertial", "spinning"] = "lvlh_fixed"
    q_ref_from_body: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    rate_body_deg_s: Vector3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _check(self) -> AttitudeConfig:
        _unit_quaternion(self.q_ref_from_body, "attitude.q_ref_from_body")
        if self.law != "spinning" and any(self.rate_body_deg_s):
            raise ValueError("rate_body_deg_s applies only to law: spinning")
        return self

    @property
    def q_ref_from_body_unit(self) -> np.ndarray:
        return _unit_quaternion(self.q_ref_from_body, "attitude.q_ref_from_body")

    @property
    def rate_body_rad_s(self) -> np.ndarray:
        return np.radians(np.asarray(self.rate_body_deg_s, dtype=np.float64))

    def build(self) -> AttitudeLaw:
        return AttitudeLaw(self.law, self.q_ref_from_body_unit, self.rate_body_rad_s)


class _ObserverBase(_Strict):
    """How the camera rolls about its boresight (see satsight.poses.attitude)."""

    camera_roll: Literal[ROLL_POLICIES] = "orbit_normal"
    roll_deg: float = 0.0


class FlyAroundConfig(_ObserverBase):
    """A natural closed relative orbit at constant range (Clohessy-Wiltshire), one
    revolution per target orbit."""

    mode: Literal["fly_around"]
    radius_km: float = Field(gt=0, le=MAX_RELATIVE_KM)
    phase_deg: float = 0.0


class FlyByConfig(_ObserverBase):
    """A co-elliptic pass: the observer drifts along-track at a constant radial offset."""

    mode: Literal["fly_by"]
    miss_distance_km: float = Field(
        ge=-MAX_RELATIVE_KM, le=MAX_RELATIVE_KM, description="radial offset; > 0 above"
    )
    start_along_track_km: float = Field(ge=-MAX_RELATIVE_KM, le=MAX_RELATIVE_KM)

    @model_validator(mode="after")
    def _passes(self) -> FlyByConfig:
        if self.miss_distance_km == 0:
            raise ValueError("miss_distance_km must be non-zero (0 would not drift)")
        if self.start_along_track_km * self.miss_distance_km <= 0:
            raise ValueError(
                "the observer never passes the target: above it (miss_distance_km > 0) it "
                "drifts towards -T, so start_along_track_km must be > 0; below it, < 0"
            )
        return self


class ApproachConfig(_ObserverBase):
    """A guided spiral approach from ``start_range_km`` to ``end_range_km`` (the paper's
    six intervals by default: 50 km to 0.5 km) in ``revolutions`` turns.

    ``schedule``: ``equal_time_per_interval`` (default) spends the same time in each
    distance interval crossed, so uniform frames are balanced over the intervals;
    ``geometric`` lets the range fall by the same factor in equal times.
    """

    mode: Literal["approach"]
    start_range_km: float = Field(default=APPROACH_INTERVALS_KM[0][0], gt=0, le=MAX_RELATIVE_KM)
    end_range_km: float = Field(default=APPROACH_INTERVALS_KM[-1][1], gt=0, le=MAX_RELATIVE_KM)
    revolutions: float = Field(default=3.0, gt=0, le=1000)
    schedule: Literal["equal_time_per_interval", "geometric"] = "equal_time_per_interval"

    def via_ranges_m(self) -> tuple[float, ...]:
        """The interval edges strictly between the start and end ranges, in order, m."""
        if self.schedule == "geometric":
            return ()
        edges = sorted({edge for interval in APPROACH_INTERVALS_KM for edge in interval})
        inside = [e for e in edges if self.end_range_km < e < self.start_range_km]
        return tuple(e * 1e3 for e in sorted(inside, reverse=True))

    @model_validator(mode="after")
    def _inwards(self) -> ApproachConfig:
        if not self.end_range_km < self.start_range_km:
            raise ValueError("end_range_km must be smaller than start_range_km")
        return self


class HoverConfig(_ObserverBase):
    """Station keeping on the target's orbit, ``range_km`` ahead of it (the paper's initial view:
    boresight along -T, image +x along N) or behind it."""

    mode: Literal["hover"]
    range_km: float = Field(default=HOVER_DISTANCE_KM, gt=0, le=MAX_RELATIVE_KM)
    side: Literal["ahead", "behind"] = "ahead"


class ObserverElementsConfig(_ObserverBase):
    """The observer on its own orbit (the paper's OE1 / OE2), propagated like the target."""

    mode: Literal["elements"]
    orbit: OrbitConfig


class RelativeRtnConfig(_ObserverBase):
    """The observer's initial state relative to the target in the target's RTN frame."""

    mode: Literal["relative_rtn"]
    position_rtn_km: Vector3
    velocity_rtn_m_s: Vector3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _apart(self) -> RelativeRtnConfig:
        if not any(self.position_rtn_km):
            raise ValueError(
                "position_rtn_km must not be [0, 0, 0]: the observer would sit inside the target"
            )
        if math.hypot(*self.position_rtn_km) > MAX_RELATIVE_KM:
            raise ValueError(
                f"position_rtn_km must lie within {MAX_RELATIVE_KM:g} km of the target"
            )
        return self


# --- trajectories from catalogued elements (TLE, OMM) and ephemeris files (OEM) ----------


def _file_key(path: Path) -> tuple[str, int, int]:
    """A cache key that changes when the file does: (resolved path, mtime_ns, size)."""
    try:
        stat = path.stat()
    except OSError:
        return (str(path), -1, -1)
    return (str(path.resolve()), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=32)
def _load_elements(
    kind: str, lines: tuple[str, ...] | None, file_key: tuple[str, int, int] | None, satellite
) -> Sgp4Orbit:
    if lines is not None:
        return select_orbit(parse_tle(list(lines), source="tle.lines"), satellite, "tle.lines")
    path = Path(file_key[0])
    orbits = read_tle_file(path) if kind == "tle" else read_omm_file(path)
    return select_orbit(orbits, satellite, str(path))


@lru_cache(maxsize=32)
def _load_oem(file_key: tuple[str, int, int]) -> OemEphemeris:
    return read_oem(Path(file_key[0]))


class TleConfig(_Strict):
    """The target (or the observer) flies a two-line element set, propagated with SGP4.

    ``lines``: the 2 lines of the set, or 3 with its name first; ``file``: a text file of one
    or more sets (CelesTrak layout); ``satellite``: which set of a file (its name or its
    catalogue number; needed when the file holds several). Without ``epoch_utc`` the
    scenario starts at the element epoch.
    """

    lines: tuple[str, ...] | None = Field(default=None, min_length=2, max_length=3)
    file: Path | None = None
    satellite: str | int | None = None

    @model_validator(mode="after")
    def _one_source(self) -> TleConfig:
        if (self.lines is None) == (self.file is None):
            raise ValueError("give exactly one of 'lines' (the TLE's 2 or 3 lines) or 'file'")
        return self

    def load(self) -> Sgp4Orbit:
        """The element set, parsed and checked (cached while the file is unchanged)."""
        key = None if self.file is None else _file_key(self.file)
        return _load_elements("tle", self.lines, key, self.satellite)

    @property
    def semi_major_axis_km(self) -> float:
        """The SGP4 mean semi-major axis, km (sets the default span and step_deg frames)."""
        return self.load().mean_semi_major_axis_m / 1e3

    def default_epoch_utc(self) -> str:
        return self.load().epoch_utc


class OmmConfig(_Strict):
    """The target (or the observer) flies CCSDS OMM mean elements (KVN, XML, or CelesTrak's
    JSON or CSV), propagated with SGP4. ``satellite`` chooses a record as for ``tle``.
    Without ``epoch_utc`` the scenario starts at the element epoch."""

    file: Path
    satellite: str | int | None = None

    def load(self) -> Sgp4Orbit:
        return _load_elements("omm", None, _file_key(self.file), self.satellite)

    @property
    def semi_major_axis_km(self) -> float:
        return self.load().mean_semi_major_axis_m / 1e3

    def default_epoch_utc(self) -> str:
        return self.load().epoch_utc


class OemConfig(_Strict):
    """The target (or the observer) follows a CCSDS OEM ephemeris file (KVN), interpolated
    as its header says. Without ``epoch_utc`` the scenario starts at the first time the file
    holds (useable and not before its first state); every frame must fall inside the span it
    holds (never extrapolated) and outside its gaps (see satsight.ephemeris.oem)."""

    file: Path

    def load(self) -> OemEphemeris:
        return _load_oem(_file_key(self.file))

    @property
    def semi_major_axis_km(self) -> float:
        """The osculating semi-major axis of the file's first state, km (vis-viva)."""
        r, v = self.load().first_state_gcrs()
        energy = 0.5 * float(v @ v) - MU_EARTH_M3_S2 / float(np.linalg.norm(r))
        if energy >= 0.0:
            raise ValueError(f"{self.file}: the first state is not on a closed orbit")
        return -MU_EARTH_M3_S2 / (2.0 * energy) / 1e3

    def default_epoch_utc(self) -> str:
        return self.load().useable_start_utc


TrajectoryConfig = OrbitConfig | TleConfig | OmmConfig | OemConfig
TRAJECTORY_KEYS = ("orbit", "tle", "omm", "oem")


class TleObserverConfig(TleConfig, _ObserverBase):
    """The observer flies its own TLE (SGP4), independently of the target."""

    mode: Literal["tle"]


class OmmObserverConfig(OmmConfig, _ObserverBase):
    """The observer flies its own OMM mean elements (SGP4), independently of the target."""

    mode: Literal["omm"]


class OemObserverConfig(OemConfig, _ObserverBase):
    """The observer follows its own OEM ephemeris file, independently of the target."""

    mode: Literal["oem"]


ABSOLUTE_TRAJECTORY_MODES = ("tle", "omm", "oem")


ObserverConfig = Annotated[
    FlyAroundConfig
    | FlyByConfig
    | ApproachConfig
    | HoverConfig
    | ObserverElementsConfig
    | RelativeRtnConfig
    | TleObserverConfig
    | OmmObserverConfig
    | OemObserverConfig,
    Field(discriminator="mode"),
]
NATURAL_SPAN_MODES = ("fly_around", "fly_by", "approach", "hover")


class SsptConfig(_Strict):
    """Sequential frames along the observer's trajectory.

    The span starts at ``start_s`` after the epoch and lasts ``duration_s`` (default: one
    target orbit for fly-around and hover, the whole pass for a fly-by, ``revolutions``
    orbits for an approach). Natural motion (every mode but the approach) starts at the
    epoch, so ``start_s`` only delays the first frame; the approach starts at ``start_s``.
    Frames are either ``frame_count`` uniform samples of the span (both ends included,
    except over a fly-around's or hover's default span of one orbit, whose end would repeat
    its start), one every ``step_s`` seconds, or, for a fly-around, one every ``step_deg``
    degrees of its revolution.
    """

    kind: Literal["sspt"]
    start_s: float = Field(default=0.0, ge=0, le=MAX_SPAN_S)
    duration_s: float | None = Field(default=None, gt=0, le=MAX_SPAN_S)
    frame_count: int | None = Field(default=None, ge=1, le=MAX_FRAMES)
    step_s: float | None = Field(default=None, gt=0)
    step_deg: float | None = Field(default=None, gt=0, le=360)

    @model_validator(mode="after")
    def _one_spacing(self) -> SsptConfig:
        given = [k for k in ("frame_count", "step_s", "step_deg") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "give exactly one of frame_count, step_s or step_deg"
                + (f" (got {', '.join(given)})" if given else "")
            )
        return self


class RssfConfig(_Strict):
    """Random views on seeded spherical Fibonacci lattices about the target, all at the
    scenario epoch, with balanced counts over the distance intervals."""

    kind: Literal["rssf"]
    frame_count: int = Field(ge=1, le=1_000_000)
    seed: int = Field(default=5, ge=0)
    intervals_km: tuple[tuple[float, float], ...] = APPROACH_INTERVALS_KM
    include_hover: bool = True
    hover_range_km: float = Field(default=HOVER_DISTANCE_KM, gt=0, le=MAX_RELATIVE_KM)
    distance_distribution: Literal["uniform", "log_uniform"] = "uniform"
    camera_roll: Literal[ROLL_POLICIES] = "orbit_normal"

    @model_validator(mode="after")
    def _intervals(self) -> RssfConfig:
        for far, near in self.intervals_km:
            if not 0 < near < far <= MAX_RELATIVE_KM:
                raise ValueError(
                    f"each interval is [far_km, near_km] with {MAX_RELATIVE_KM:g} >= far > near "
                    f"> 0; got {[far, near]}"
                )
        if not self.intervals_km and not self.include_hover:
            raise ValueError("no distance interval: give intervals_km or include_hover: true")
        return self


SamplerConfig = Annotated[SsptConfig | RssfConfig, Field(discriminator="kind")]


class VisibilityConfig(_Strict):
    """Which frames count as observable, and what to do with the others.

    ``on_fail``: ``flag`` renders every frame and records the failed tests in the labels;
    ``skip`` leaves failing frames out of the dataset (the plan still lists them);
    ``keep`` applies no limits (the measured values are still recorded).
    """

    atmosphere_margin_km: float = Field(default=DEFAULT_ATMOSPHERE_MARGIN_M / 1e3, ge=0)
    min_sunlit_fraction: float = Field(default=1.0, ge=0, le=1)
    sun_exclusion_deg: float = Field(default=30.0, ge=0, le=180)
    min_phase_angle_deg: float = Field(default=0.0, ge=0, le=180)
    max_phase_angle_deg: float = Field(default=150.0, ge=0, le=180)
    on_fail: Literal["flag", "skip", "keep"] = "flag"

    @model_validator(mode="after")
    def _ordered(self) -> VisibilityConfig:
        if self.min_phase_angle_deg > self.max_phase_angle_deg:
            raise ValueError("min_phase_angle_deg must not exceed max_phase_angle_deg")
        return self

    def limits(self) -> VisibilityLimits:
        return VisibilityLimits(
            atmosphere_margin_m=self.atmosphere_margin_km * 1e3,
            min_sunlit_fraction=self.min_sunlit_fraction,
            sun_exclusion_rad=math.radians(self.sun_exclusion_deg),
            min_phase_angle_rad=math.radians(self.min_phase_angle_deg),
            max_phase_angle_rad=math.radians(self.max_phase_angle_deg),
        )


class PropagationConfig(_Strict):
    """How both spacecraft are propagated: RK4 at a fixed step (the paper: 1 s) or DOP853.

    j2: the Earth's oblateness. j2_axis: ``true_pole`` (the ITRS pole at each instant, from
    the scenario's epoch; default) or ``gcrs_z`` (the GCRS z axis: an approximation that
    moves a LEO satellite by up to ~0.4 km per orbit at 2025 and ~0.9 km at 2050, see
    docs/design.md); without an epoch the GCRS z axis is used. max_zonal_degree: 2 (J2), 3
    or 4 (J3, J4; EGM96).
    """

    method: Literal["rk4", "dop853"] = "rk4"
    step_s: float = Field(default=1.0, gt=0, le=600)
    j2: bool = True
    j2_axis: Literal["true_pole", "gcrs_z"] = "true_pole"
    max_zonal_degree: int = Field(default=2, ge=2, le=4)
