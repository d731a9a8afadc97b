"""The scenario's ``randomize`` section: which groups vary from frame to frame, and within
what ranges.

Each group is ``false`` (the default: fixed for the dataset), ``true`` (the documented
default ranges) or a mapping of ranges; every range given replaces its default, the others
keep theirs. Angles in degrees and small lengths in micrometres here (the key says so);
``build`` turns them into SI ``satsight.randomization.ranges`` dataclasses.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, model_validator

from satsight.errors import SatsightError
from satsight.randomization.ranges import (
    EarthRanges,
    MaterialRanges,
    PoseRanges,
    RandomizationRanges,
    SensorRanges,
    SunRanges,
)

Pair = tuple[float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _um(pair: Pair) -> Pair:
    return (round(pair[0] * 1e6, 9), round(pair[1] * 1e6, 9))


def _deg(pair: Pair) -> Pair:
    return (math.degrees(pair[0]), math.degrees(pair[1]))


class MaterialsRandomizeConfig(_Strict):
    """Per material: the chance it is swapped for another library material of its family,
    then factors on its roughness and base colour and a shift of its IOR; and whether
    seeded texture patterns (MLI crinkle) are drawn anew each frame."""

    roughness_scale: Pair = MaterialRanges().roughness_scale
    base_color_scale: Pair = MaterialRanges().base_color_scale
    ior_shift: Pair = MaterialRanges().ior_shift
    swap_probability: float = MaterialRanges().swap_probability
    reseed_textures: bool = MaterialRanges().reseed_textures

    def build(self) -> MaterialRanges:
        return MaterialRanges(
            self.roughness_scale,
            self.base_color_scale,
            self.ior_shift,
            self.swap_probability,
            self.reseed_textures,
        )


class SunRandomizeConfig(_Strict):
    """Factor on the Sun's in-band irradiance; its direction turned by up to
    ``direction_jitter_deg`` on hand-placed views (on orbit plans too with
    ``jitter_orbit_frames``)."""

    irradiance_scale: Pair = SunRanges().irradiance_scale
    direction_jitter_deg: float = math.degrees(SunRanges().direction_jitter_rad)
    jitter_orbit_frames: bool = False

    def build(self) -> SunRanges:
        return SunRanges(
            self.irradiance_scale, math.radians(self.direction_jitter_deg), self.jitter_orbit_frames
        )


class EarthRandomizeConfig(_Strict):
    """Factor on a uniform Earth's albedo, the chance the Earth is drawn with its albedo map
    (else uniform), how many cloud patterns the map's clouds are drawn from (each new one
    costs ~20 s once), the range of the map's mean cloud cover (drawn among levels ~0.05
    apart, each level's map built once; default the scenario's), and on hand-placed views
    the chance that the Earth is moved behind the target. Applies where the scenario has
    ``earth``."""

    albedo_scale: Pair = EarthRanges().albedo_scale
    surface_map_probability: float = EarthRanges().surface_map_probability
    cloud_patterns: int = EarthRanges().cloud_patterns
    behind_probability: float = EarthRanges().behind_probability
    cloud_fraction: Pair | None = None

    def build(self) -> EarthRanges:
        return EarthRanges(
            self.albedo_scale,
            self.surface_map_probability,
            self.cloud_patterns,
            self.behind_probability,
            self.cloud_fraction,
        )


class SensorRandomizeConfig(_Strict):
    """Factors on the exposure time, read noise, gain and PRNU; the optics' defocus disc
    (um) and line-of-sight jitter (urad rms)."""

    exposure_factor: Pair = SensorRanges().exposure_factor
    read_noise_scale: Pair = SensorRanges().read_noise_scale
    gain_scale: Pair = SensorRanges().gain_scale
    prnu_scale: Pair = SensorRanges().prnu_scale
    defocus_blur_diameter_um: Pair = _um(SensorRanges().defocus_blur_diameter_m)
    jitter_rms_urad: Pair = _um(SensorRanges().jitter_rms_rad)

    def build(self) -> SensorRanges:
        return SensorRanges(
            self.exposure_factor,
            self.read_noise_scale,
            self.gain_scale,
            self.prnu_scale,
            (self.defocus_blur_diameter_um[0] / 1e6, self.defocus_blur_diameter_um[1] / 1e6),
            (self.jitter_rms_urad[0] / 1e6, self.jitter_rms_urad[1] / 1e6),
        )


class PoseRandomizeConfig(_Strict):
    """The camera's roll about its boresight, and the target's attitude jitter about its
    box centre (labels follow both)."""

    roll_deg: Pair = _deg(PoseRanges().roll_rad)
    attitude_jitter_deg: float = math.degrees(PoseRanges().attitude_jitter_rad)

    def build(self) -> PoseRanges:
        return PoseRanges(
            (math.radians(self.roll_deg[0]), math.radians(self.roll_deg[1])),
            math.radians(self.attitude_jitter_deg),
        )


class RandomizeConfig(_Strict):
    """Seeded domain randomisation (module docstring). Each frame's draws come from its own
    seed streams and are written in its labels under ``randomized``."""

    materials: bool | MaterialsRandomizeConfig = False
    sun: bool | SunRandomizeConfig = False
    earth: bool | EarthRandomizeConfig = False
    sensor: bool | SensorRandomizeConfig = False
    pose: bool | PoseRandomizeConfig = False

    @model_validator(mode="after")
    def _check(self) -> RandomizeConfig:
        try:
            self.build()
        except SatsightError as error:
            raise ValueError(str(error)) from None
        return self

    def build(self) -> RandomizationRanges | None:
        """The ranges of the groups that vary, or None when none does."""
        defaults = {
            "materials": MaterialsRandomizeConfig,
            "sun": SunRandomizeConfig,
            "earth": EarthRandomizeConfig,
            "sensor": SensorRandomizeConfig,
            "pose": PoseRandomizeConfig,
        }
        groups = {}
        for name, model in defaults.items():
            value = getattr(self, name)
            if value is True:
                value = model()
            groups[name] = None if value is False else value.build()
        ranges = RandomizationRanges(**groups)
        return ranges if ranges.groups else None
