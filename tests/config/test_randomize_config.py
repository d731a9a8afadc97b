"""The scenario's randomize section: true gives the documented defaults, a mapping
replaces only the ranges it names, and bad ranges are one clear message."""

from __future__ import annotations

import math

import pytest
from pydantic import ValidationError

from satsight.config.randomize import RandomizeConfig
from satsight.randomization.ranges import PoseRanges, SensorRanges


def test_nothing_varies_by_default() -> None:
    assert RandomizeConfig().build() is None


def test_true_gives_the_default_ranges_and_a_mapping_replaces_only_its_keys() -> None:
    ranges = RandomizeConfig.model_validate(
        {"sensor": True, "pose": {"roll_deg": [-10, 10]}}
    ).build()
    assert ranges.groups == ("sensor", "pose")
    assert ranges.sensor == SensorRanges()
    assert ranges.sensor.defocus_blur_diameter_m == (0.0, 30e-6)
    assert ranges.pose.roll_rad == pytest.approx((-math.radians(10), math.radians(10)))
    assert ranges.pose.attitude_jitter_rad == pytest.approx(PoseRanges().attitude_jitter_rad)


def test_texture_reseeding_follows_the_materials_group() -> None:
    """On with the materials group by default; ``reseed_textures: false`` keeps the
    scenario's textures."""
    assert RandomizeConfig.model_validate({"materials": True}).build().materials.reseed_textures
    kept = RandomizeConfig.model_validate({"materials": {"reseed_textures": False}}).build()
    assert kept.materials.reseed_textures is False


@pytest.mark.parametrize(
    ("section", "message"),
    [
        (
            {"sensor": {"gain_scale": [2, 1]}},
            r"sensor\.gain_scale must be \[low, high\]",
        ),
        ({"earth": {"cloud_patterns": 0}}, r"cloud_patterns must be a whole number within"),
        ({"earth": {"cloud_fraction": [0.2, 0.5]}}, r"cloud_fraction must lie within \[0.3, 1\]"),
        ({"sensor": {"exposure_factor": [0, 2]}}, r"must lie within|log-uniform"),
        ({"sun": {"direction_jitter_deg": 200}}, r"direction_jitter_deg must be within \[0, 180\]"),
        ({"pose": {"spin": True}}, r"spin"),
    ],
)
def test_bad_ranges_are_named(section: dict, message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        RandomizeConfig.model_validate(section)
