"""The ranges of the randomised groups (frozen dataclasses, SI units unless the name says).

Each group is off (None in ``RandomizationRanges``) or a set of ranges; an interval is
(low, high) with low <= high, drawn uniformly unless its field says log-uniform (scales
spanning a factor of several, where each octave should be as likely). The defaults are
those ``randomize: {group: true}`` gives; docs/design.md ("Domain randomisation") gives
the reasons for each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from satsight.errors import SatsightError

Interval = tuple[float, float]


def check_interval(name: str, interval: Interval, low: float, high: float) -> Interval:
    """(a, b) as floats, with low <= a <= b <= high; else a SatsightError naming ``name``."""
    try:
        a, b = (float(v) for v in interval)
    except (TypeError, ValueError):
        raise SatsightError(
            f"{name} must be a pair [low, high] of numbers, got {interval!r}"
        ) from None
    if not (math.isfinite(a) and math.isfinite(b)) or a > b:
        raise SatsightError(f"{name} must be [low, high] with low <= high, got [{a:g}, {b:g}]")
    if a < low or b > high:
        raise SatsightError(f"{name} must lie within [{low:g}, {high:g}], got [{a:g}, {b:g}]")
    return a, b


def check_cap_angle(name: str, angle_rad: float) -> None:
    """A cap's half-angle within [0, pi]; else a SatsightError naming ``name`` (in deg)."""
    if not 0.0 <= angle_rad <= math.pi:
        raise SatsightError(f"{name} must be within [0, 180], got {math.degrees(angle_rad):g}")


@dataclass(frozen=True)
class MaterialRanges:
    """Per material of the target (every part made of it changes alike).

    roughness_scale: factor on the GGX roughness (result clipped to [0.02, 1]).
    base_color_scale: factor on the base colour, the same for the three channels (result
    clipped to 1 per channel, so no material reflects more than it receives).
    ior_shift: added to the index of refraction (result at least 1.05).
    swap_probability: the chance that the material is first replaced by another library
    material of its family (``satsight.scene.material_families``; none for a material
    without a family or alone in it). reseed_textures: seeded texture patterns (MLI
    crinkle) are drawn anew each frame.
    """

    roughness_scale: Interval = (0.7, 1.4)
    base_color_scale: Interval = (0.8, 1.2)
    ior_shift: Interval = (-0.1, 0.1)
    swap_probability: float = 0.25
    reseed_textures: bool = True

    def __post_init__(self) -> None:
        check_interval("randomize.materials.roughness_scale", self.roughness_scale, 0.0, 10.0)
        check_interval("randomize.materials.base_color_scale", self.base_color_scale, 0.0, 10.0)
        check_interval("randomize.materials.ior_shift", self.ior_shift, -1.0, 1.0)
        if not 0.0 <= self.swap_probability <= 1.0:
            raise SatsightError(
                "randomize.materials.swap_probability must be within [0, 1], got "
                f"{self.swap_probability:g}"
            )
        if not isinstance(self.reseed_textures, bool):
            raise SatsightError("randomize.materials.reseed_textures must be true or false")


@dataclass(frozen=True)
class SunRanges:
    """irradiance_scale: factor on the Sun's in-band irradiance (the solar constant varies
    by ~0.1 % and the Earth-Sun distance by +-1.7 %; the default +-5 % also stands for
    calibration error). direction_jitter_rad: the Sun's direction turns by an angle up to
    this (uniform over the spherical cap); only on hand-placed views unless
    ``jitter_orbit_frames`` (an orbit plan's Sun is where the ephemeris puts it)."""

    irradiance_scale: Interval = (0.95, 1.05)
    direction_jitter_rad: float = math.radians(5.0)
    jitter_orbit_frames: bool = False

    def __post_init__(self) -> None:
        check_interval("randomize.sun.irradiance_scale", self.irradiance_scale, 0.0, 100.0)
        check_cap_angle("randomize.sun.direction_jitter_deg", self.direction_jitter_rad)


#: The Earth moved behind the target has its centre within this fraction of its angular
#: radius (seen from the target) of the line of sight, so the target is seen against it.
EARTH_BEHIND_CAP_FRACTION = 0.8


#: About how far apart the drawn levels of the cloud cover are (``EarthRanges``).
CLOUD_FRACTION_STEP = 0.05
#: The lowest cloud cover a randomised map may draw (``EarthRanges``).
CLOUD_FRACTION_MIN = 0.3


def cloud_fraction_levels(interval: Interval) -> np.ndarray:
    """The cloud-cover levels of ``interval`` [low, high]: evenly spaced from low to high,
    about ``CLOUD_FRACTION_STEP`` apart (one level when low == high)."""
    low, high = interval
    count = max(1, round((high - low) / CLOUD_FRACTION_STEP) + 1)
    return np.linspace(low, high, count)


@dataclass(frozen=True)
class EarthRanges:
    """albedo_scale: factor on the albedo of a uniform Earth (clipped to 1); a mapped Earth
    keeps its map's values. surface_map_probability: the chance that the Earth is drawn
    with its albedo map, else uniform. cloud_patterns: the map's clouds are one of this many
    patterns (the scenario's cloud seed and the next ones); each new pattern's map is built
    once, in ~20 s on two cores, then read from the disk cache. cloud_fraction: the map's
    mean cloud cover drawn among evenly spaced levels from its low to its high end about
    ``CLOUD_FRACTION_STEP`` apart (``cloud_fraction_levels``), each level's map built once
    (~1.5 s once its pattern is in memory); None keeps the scenario's. behind_probability: on
    hand-placed views, the chance that the Earth is moved behind the target, its centre
    within ``EARTH_BEHIND_CAP_FRACTION`` of its angular radius of the line of sight (else
    it stays where the scenario puts it)."""

    albedo_scale: Interval = (0.8, 1.2)
    surface_map_probability: float = 0.8
    cloud_patterns: int = 1
    behind_probability: float = 0.5
    cloud_fraction: Interval | None = None

    def __post_init__(self) -> None:
        check_interval("randomize.earth.albedo_scale", self.albedo_scale, 0.0, 10.0)
        if not 0.0 <= self.surface_map_probability <= 1.0:
            raise SatsightError(
                "randomize.earth.surface_map_probability must be within [0, 1], got "
                f"{self.surface_map_probability:g}"
            )
        if not 0.0 <= self.behind_probability <= 1.0:
            raise SatsightError(
                "randomize.earth.behind_probability must be within [0, 1], got "
                f"{self.behind_probability:g}"
            )
        if self.cloud_fraction is not None:
            # The map's cloud albedo, (Bond albedo - clear share) / cover, must stay <= 1:
            # at cover 0.2 it is 0.98-1.02 over the cloud patterns (seeds 0-7), at 0.3
            # about 0.7, which leaves room for every pattern.
            fraction = check_interval(
                "randomize.earth.cloud_fraction", self.cloud_fraction, CLOUD_FRACTION_MIN, 1.0
            )
            object.__setattr__(self, "cloud_fraction", fraction)
        if isinstance(self.cloud_patterns, bool) or not 1 <= self.cloud_patterns <= 64:
            raise SatsightError(
                "randomize.earth.cloud_patterns must be a whole number within [1, 64], got "
                f"{self.cloud_patterns!r}"
            )


@dataclass(frozen=True)
class SensorRanges:
    """exposure_factor: factor on the exposure time the rule gives (log-uniform).
    read_noise_scale, gain_scale, prnu_scale: factors on the detector's read noise,
    conversion gain (e-/DN) and PRNU (log-uniform, uniform, log-uniform; PRNU at most 20 %).
    defocus_blur_diameter_m, jitter_rms_rad: the optics' defocus disc and line-of-sight
    jitter, drawn uniformly (they replace the camera's values)."""

    exposure_factor: Interval = (0.5, 2.0)
    read_noise_scale: Interval = (0.5, 2.0)
    gain_scale: Interval = (0.9, 1.1)
    prnu_scale: Interval = (0.5, 2.0)
    defocus_blur_diameter_m: Interval = (0.0, 30e-6)
    jitter_rms_rad: Interval = (0.0, 2e-6)

    def __post_init__(self) -> None:
        for name, low, high in (
            ("exposure_factor", 1e-3, 1e3),
            ("read_noise_scale", 0.0, 100.0),
            ("gain_scale", 1e-3, 1e3),
            ("prnu_scale", 0.0, 100.0),
            ("defocus_blur_diameter_m", 0.0, 1e-3),
            ("jitter_rms_rad", 0.0, 1e-3),
        ):
            check_interval(f"randomize.sensor.{name}", getattr(self, name), low, high)
        for name in ("exposure_factor", "read_noise_scale", "prnu_scale"):
            if getattr(self, name)[0] <= 0.0:
                raise SatsightError(f"randomize.sensor.{name} is log-uniform: its low must be > 0")


@dataclass(frozen=True)
class PoseRanges:
    """roll_rad: the camera turns about its boresight by this (uniform; labels follow).
    attitude_jitter_rad: the target turns about its box centre by an angle up to this, about
    an axis uniform on the sphere (uniform over the cap of rotations' axes times angle)."""

    roll_rad: Interval = (-math.pi, math.pi)
    attitude_jitter_rad: float = math.radians(2.0)

    def __post_init__(self) -> None:
        check_interval("randomize.pose.roll_deg", self.roll_rad, -math.pi, math.pi)
        check_cap_angle("randomize.pose.attitude_jitter_deg", self.attitude_jitter_rad)


@dataclass(frozen=True)
class RandomizationRanges:
    """The groups that vary (None: the group is fixed for the whole dataset)."""

    materials: MaterialRanges | None = None
    sun: SunRanges | None = None
    earth: EarthRanges | None = None
    sensor: SensorRanges | None = None
    pose: PoseRanges | None = None

    @property
    def groups(self) -> tuple[str, ...]:
        """The names of the groups that vary, in a fixed order."""
        return tuple(f.name for f in fields(self) if getattr(self, f.name) is not None)
