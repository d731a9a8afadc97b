"""One frame's randomised values, each group from its own seed stream.

A group's generator is ``default_rng(SeedSequence([seed, plan_index, tag]))`` with ``tag``
the CRC-32 of the group's name (a material's stream adds the CRC-32 of the material's
name), so a frame's draws depend only on the scenario seed, its plan index and the ranges:
never on which frames a process renders, nor on the other groups (turning one group on
leaves the others' values unchanged). Each group draws the same count of numbers whatever
its ranges. The tags never equal the detector noise's stream ([seed, frame, 1]).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import asdict, dataclass

import numpy as np

from satsight.randomization.ranges import (
    EarthRanges,
    Interval,
    MaterialRanges,
    PoseRanges,
    RandomizationRanges,
    SensorRanges,
    SunRanges,
    cloud_fraction_levels,
)


def _tag(name: str) -> int:
    return zlib.crc32(name.encode("utf-8"))


def group_rng(seed: int, plan_index: int, group: str, item: str | None = None):
    """The generator of one group's draws for one frame (of one item, e.g. a material)."""
    key = [int(seed), int(plan_index), _tag(f"randomize.{group}")]
    if item is not None:
        key.append(_tag(item))
    return np.random.default_rng(np.random.SeedSequence(key))


def _uniform(u: float, interval: Interval) -> float:
    return interval[0] + u * (interval[1] - interval[0])


def _log_uniform(u: float, interval: Interval) -> float:
    low, high = math.log(interval[0]), math.log(interval[1])
    return math.exp(low + u * (high - low))


def cap_angle_rad(u: float, half_angle_rad: float) -> float:
    """The polar angle of a direction uniform over the spherical cap of ``half_angle_rad``
    about the pole, from u uniform in [0, 1): cos(theta) uniform in [cos(half angle), 1]."""
    return math.acos(1.0 - u * (1.0 - math.cos(half_angle_rad)))


def unit_vector(u: float, v: float) -> np.ndarray:
    """A direction uniform on the unit sphere from u, v uniform in [0, 1)."""
    z = 1.0 - 2.0 * u
    r = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * v
    return np.array([r * math.cos(phi), r * math.sin(phi), z])


@dataclass(frozen=True)
class MaterialDraw:
    """Factors and shift of one material (``MaterialRanges``); swap: whether it is first
    replaced by another of its family, the one at ``swap_choice`` (in [0, 1)) of the list."""

    roughness_scale: float
    base_color_scale: float
    ior_shift: float
    swap: bool = False
    swap_choice: float = 0.0


@dataclass(frozen=True)
class SunDraw:
    """irradiance_scale; the Sun's direction turned by ``direction_jitter_rad`` towards
    ``jitter_azimuth_rad`` (about the direction, from an axis fixed by ``apply``)."""

    irradiance_scale: float
    direction_jitter_rad: float
    jitter_azimuth_rad: float


@dataclass(frozen=True)
class EarthDraw:
    """albedo_scale (a uniform Earth's); surface "map" or "uniform"; cloud_pattern: which
    of the patterns (0 the scenario's cloud seed, k its seed + k); behind: the Earth is
    moved behind the target, its centre off the line of sight by the cap angle of
    ``behind_offset_u`` (a uniform number) towards ``behind_azimuth_rad``; cloud_fraction:
    the map's mean cloud cover (None: the scenario's)."""

    albedo_scale: float
    surface: str
    cloud_pattern: int
    behind: bool = False
    behind_offset_u: float = 0.0
    behind_azimuth_rad: float = 0.0
    cloud_fraction: float | None = None


@dataclass(frozen=True)
class SensorDraw:
    exposure_factor: float
    read_noise_scale: float
    gain_scale: float
    prnu_scale: float
    defocus_blur_diameter_m: float
    jitter_rms_rad: float


@dataclass(frozen=True)
class PoseDraw:
    """roll_rad about the camera's boresight; the target turned by attitude_jitter_rad
    about ``jitter_axis_body`` (unit, body frame) through its box centre."""

    roll_rad: float
    attitude_jitter_rad: float
    jitter_axis_body: tuple[float, float, float]


@dataclass(frozen=True)
class FrameDraws:
    """One frame's draws (None for a group that does not vary). texture_seed: the seed of
    the frame's seeded texture patterns (its own stream, "randomize.textures"), with
    ``materials.reseed_textures``."""

    materials: dict[str, MaterialDraw] | None = None
    sun: SunDraw | None = None
    earth: EarthDraw | None = None
    sensor: SensorDraw | None = None
    pose: PoseDraw | None = None
    texture_seed: int | None = None


def draw_materials(
    ranges: MaterialRanges, seed: int, plan_index: int, names: list[str]
) -> dict[str, MaterialDraw]:
    out = {}
    for name in sorted(names):
        u = group_rng(seed, plan_index, "materials", name).random(5)
        out[name] = MaterialDraw(
            roughness_scale=_uniform(u[0], ranges.roughness_scale),
            base_color_scale=_uniform(u[1], ranges.base_color_scale),
            ior_shift=_uniform(u[2], ranges.ior_shift),
            swap=bool(u[3] < ranges.swap_probability),
            swap_choice=float(u[4]),
        )
    return out


def draw_sun(ranges: SunRanges, seed: int, plan_index: int, hand_placed: bool) -> SunDraw:
    u = group_rng(seed, plan_index, "sun").random(3)
    jitter = hand_placed or ranges.jitter_orbit_frames
    return SunDraw(
        irradiance_scale=_uniform(u[0], ranges.irradiance_scale),
        direction_jitter_rad=cap_angle_rad(u[1], ranges.direction_jitter_rad) if jitter else 0.0,
        jitter_azimuth_rad=2.0 * math.pi * u[2] if jitter else 0.0,
    )


def draw_earth(ranges: EarthRanges, seed: int, plan_index: int) -> EarthDraw:
    # The cover's number comes last: the others are the same with it or without it.
    u = group_rng(seed, plan_index, "earth").random(7)
    cloud_fraction = None
    if ranges.cloud_fraction is not None:
        levels = cloud_fraction_levels(ranges.cloud_fraction)
        cloud_fraction = float(levels[min(int(u[6] * len(levels)), len(levels) - 1)])
    return EarthDraw(
        albedo_scale=_uniform(u[0], ranges.albedo_scale),
        surface="map" if u[1] < ranges.surface_map_probability else "uniform",
        cloud_pattern=min(int(u[2] * ranges.cloud_patterns), ranges.cloud_patterns - 1),
        behind=bool(u[3] < ranges.behind_probability),
        behind_offset_u=float(u[4]),
        behind_azimuth_rad=2.0 * math.pi * float(u[5]),
        cloud_fraction=cloud_fraction,
    )


def draw_sensor(ranges: SensorRanges, seed: int, plan_index: int) -> SensorDraw:
    u = group_rng(seed, plan_index, "sensor").random(6)
    return SensorDraw(
        exposure_factor=_log_uniform(u[0], ranges.exposure_factor),
        read_noise_scale=_log_uniform(u[1], ranges.read_noise_scale),
        gain_scale=_uniform(u[2], ranges.gain_scale),
        prnu_scale=_log_uniform(u[3], ranges.prnu_scale),
        defocus_blur_diameter_m=_uniform(u[4], ranges.defocus_blur_diameter_m),
        jitter_rms_rad=_uniform(u[5], ranges.jitter_rms_rad),
    )


def draw_pose(ranges: PoseRanges, seed: int, plan_index: int) -> PoseDraw:
    u = group_rng(seed, plan_index, "pose").random(4)
    axis = unit_vector(u[2], u[3])
    # The angle is distributed as the polar angle of a direction uniform over the cap of
    # half-angle J (density ~ sin(angle)), so a turned body axis covers its cap evenly.
    return PoseDraw(
        roll_rad=_uniform(u[0], ranges.roll_rad),
        attitude_jitter_rad=cap_angle_rad(u[1], ranges.attitude_jitter_rad),
        jitter_axis_body=tuple(float(c) for c in axis),
    )


def draw_frame(
    ranges: RandomizationRanges,
    seed: int,
    plan_index: int,
    material_names: list[str],
    hand_placed: bool,
) -> FrameDraws:
    """Every varying group's draws for plan frame ``plan_index``."""
    return FrameDraws(
        materials=None
        if ranges.materials is None
        else draw_materials(ranges.materials, seed, plan_index, material_names),
        sun=None if ranges.sun is None else draw_sun(ranges.sun, seed, plan_index, hand_placed),
        earth=None if ranges.earth is None else draw_earth(ranges.earth, seed, plan_index),
        sensor=None if ranges.sensor is None else draw_sensor(ranges.sensor, seed, plan_index),
        pose=None if ranges.pose is None else draw_pose(ranges.pose, seed, plan_index),
        texture_seed=None
        if ranges.materials is None or not ranges.materials.reseed_textures
        else int(group_rng(seed, plan_index, "textures").integers(0, 2**62)),
    )


def draw_record(draw) -> dict:
    """A draw as plain JSON values."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(draw).items()}
