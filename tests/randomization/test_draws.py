"""Each frame's randomised draws: seeded per frame and group, independent of the other
groups, and distributed as documented (means within sample-count tolerances)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.randomization.draws import (
    cap_angle_rad,
    draw_earth,
    draw_frame,
    draw_materials,
    draw_pose,
    draw_sensor,
    draw_sun,
    group_rng,
    unit_vector,
)
from satsight.randomization.ranges import (
    EarthRanges,
    MaterialRanges,
    PoseRanges,
    RandomizationRanges,
    SensorRanges,
    SunRanges,
    cloud_fraction_levels,
)

ALL = RandomizationRanges(
    MaterialRanges(), SunRanges(), EarthRanges(), SensorRanges(), PoseRanges()
)
N_FRAMES = 4000
#: Bound on a sample mean's deviation, in standard errors (a 4-sigma miss is 6e-5 likely).
Z = 4.0


def test_the_same_frame_draws_the_same_values_and_frames_differ() -> None:
    a = draw_frame(ALL, 7, 12, ["gold", "cfrp"], hand_placed=True)
    assert a == draw_frame(ALL, 7, 12, ["cfrp", "gold"], hand_placed=True)
    assert a.sensor != draw_frame(ALL, 7, 13, ["gold", "cfrp"], True).sensor
    assert a.sensor != draw_frame(ALL, 8, 12, ["gold", "cfrp"], True).sensor


def test_a_group_does_not_depend_on_the_others_or_on_the_other_materials() -> None:
    only_sensor = RandomizationRanges(sensor=SensorRanges())
    assert draw_frame(only_sensor, 3, 5, [], True).sensor == draw_frame(ALL, 3, 5, [], True).sensor
    assert draw_frame(only_sensor, 3, 5, [], True).pose is None
    one = draw_materials(MaterialRanges(), 3, 5, ["gold"])
    two = draw_materials(MaterialRanges(), 3, 5, ["gold", "aluminium"])
    assert one["gold"] == two["gold"]


def test_streams_are_not_the_detector_noise_stream() -> None:
    noise = np.random.default_rng(np.random.SeedSequence([4, 9, 1])).random(4)
    for group in ("materials", "sun", "earth", "sensor", "pose"):
        assert not np.array_equal(group_rng(4, 9, group).random(4), noise)


def test_uniform_and_log_uniform_draws_have_the_expected_means() -> None:
    ranges = SensorRanges(gain_scale=(0.9, 1.1), exposure_factor=(0.25, 4.0))
    draws = [draw_sensor(ranges, 1, i) for i in range(N_FRAMES)]
    gain = np.array([d.gain_scale for d in draws])
    sem = 0.2 / math.sqrt(12 * N_FRAMES)
    assert abs(gain.mean() - 1.0) < Z * sem
    assert gain.min() >= 0.9 and gain.max() <= 1.1
    # Log-uniform: log of the factor uniform over [log 0.25, log 4].
    log_factor = np.log([d.exposure_factor for d in draws])
    width = math.log(16.0)
    assert abs(log_factor.mean()) < Z * width / math.sqrt(12 * N_FRAMES)
    assert log_factor.std() == pytest.approx(width / math.sqrt(12), rel=0.05)


def test_cap_angles_are_uniform_over_the_caps_area() -> None:
    half_angle = math.radians(30.0)
    u = np.random.default_rng(0).random(N_FRAMES)
    theta = np.array([cap_angle_rad(x, half_angle) for x in u])
    assert theta.max() <= half_angle
    # Area up to theta is proportional to 1 - cos(theta): half the cap lies within the
    # angle whose 1 - cos is half of 1 - cos(half_angle).
    median = math.acos(1.0 - 0.5 * (1.0 - math.cos(half_angle)))
    inside = np.mean(theta < median)
    assert abs(inside - 0.5) < Z * 0.5 / math.sqrt(N_FRAMES)


def test_unit_vectors_are_uniform_on_the_sphere() -> None:
    u = np.random.default_rng(1).random((N_FRAMES, 2))
    v = np.array([unit_vector(a, b) for a, b in u])
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, rtol=0, atol=1e-12)
    # Each component of a uniform direction has mean 0 and variance 1/3.
    assert np.all(np.abs(v.mean(axis=0)) < Z * math.sqrt(1 / 3 / N_FRAMES))


def test_sun_jitter_only_on_hand_placed_views_unless_asked() -> None:
    ranges = SunRanges()
    assert draw_sun(ranges, 0, 3, hand_placed=False).direction_jitter_rad == 0.0
    assert draw_sun(ranges, 0, 3, hand_placed=True).direction_jitter_rad > 0.0
    orbit_too = SunRanges(jitter_orbit_frames=True)
    assert draw_sun(orbit_too, 0, 3, hand_placed=False).direction_jitter_rad > 0.0
    # The irradiance factor is the same either way (one stream, same count of numbers).
    assert (
        draw_sun(ranges, 0, 3, False).irradiance_scale
        == draw_sun(ranges, 0, 3, True).irradiance_scale
    )


def test_pose_draws_stay_in_their_ranges() -> None:
    ranges = PoseRanges(roll_rad=(-0.5, 0.25), attitude_jitter_rad=0.1)
    for i in range(200):
        d = draw_pose(ranges, 2, i)
        assert -0.5 <= d.roll_rad <= 0.25
        assert 0.0 <= d.attitude_jitter_rad <= 0.1
        assert np.linalg.norm(d.jitter_axis_body) == pytest.approx(1.0, abs=1e-12)


def test_earth_draws_pick_every_cloud_pattern_and_the_map_at_its_rate() -> None:
    ranges = EarthRanges(surface_map_probability=0.7, cloud_patterns=4)
    draws = [draw_earth(ranges, 5, i) for i in range(N_FRAMES)]
    counts = np.bincount([d.cloud_pattern for d in draws], minlength=4)
    assert counts.size == 4
    # Each pattern's share: binomial with p = 1/4.
    assert np.all(np.abs(counts / N_FRAMES - 0.25) < Z * math.sqrt(0.25 * 0.75 / N_FRAMES))
    mapped = np.mean([d.surface == "map" for d in draws])
    assert abs(mapped - 0.7) < Z * math.sqrt(0.7 * 0.3 / N_FRAMES)
    assert all(0.8 <= d.albedo_scale <= 1.2 for d in draws)


def test_the_cloud_cover_is_drawn_among_its_levels_and_changes_no_other_draw() -> None:
    """[0.5, 0.8] gives the seven levels 0.5, 0.55 .. 0.8, each drawn with probability
    1/7 (binomial bounds); the cover's number comes after the others, so every other
    Earth draw of a frame is the one drawn without it."""
    assert np.allclose(cloud_fraction_levels((0.5, 0.8)), np.arange(7) * 0.05 + 0.5)
    assert np.allclose(cloud_fraction_levels((0.6, 0.6)), [0.6])
    assert len(cloud_fraction_levels((0.3, 0.32))) == 1  # less than half a step apart
    ranges = EarthRanges(cloud_fraction=(0.5, 0.8))
    draws = [draw_earth(ranges, 9, i) for i in range(N_FRAMES)]
    levels = np.round((np.array([d.cloud_fraction for d in draws]) - 0.5) / 0.05)
    counts = np.bincount(levels.astype(int), minlength=7)
    assert counts.size == 7
    assert np.all(np.abs(counts / N_FRAMES - 1 / 7) < Z * math.sqrt(1 / 7 * 6 / 7 / N_FRAMES))
    plain = [draw_earth(EarthRanges(), 9, i) for i in range(50)]
    assert all(p.cloud_fraction is None for p in plain)
    for with_cover, without in zip(draws, plain, strict=False):
        assert dataclasses.replace(with_cover, cloud_fraction=None) == without


def test_materials_are_swapped_at_their_probability() -> None:
    ranges = MaterialRanges(swap_probability=0.3)
    draws = [draw_materials(ranges, 4, i, ["gold"])["gold"] for i in range(N_FRAMES)]
    rate = np.mean([d.swap for d in draws])
    assert abs(rate - 0.3) < Z * math.sqrt(0.3 * 0.7 / N_FRAMES)
    # The swap draws come after the others: turning swaps off changes no factor.
    off = draw_materials(MaterialRanges(swap_probability=0.0), 4, 7, ["gold"])["gold"]
    assert not off.swap and off.roughness_scale == draws[7].roughness_scale


def test_texture_seeds_come_from_their_own_stream_with_reseeding_on() -> None:
    """With ``reseed_textures`` every frame draws a texture seed from the stream
    "randomize.textures" (the same frame the same seed, frames apart), and the other
    groups' draws do not change; without it, or without the materials group, none."""
    a = draw_frame(ALL, 7, 12, ["gold"], hand_placed=True)
    assert a.texture_seed == int(group_rng(7, 12, "textures").integers(0, 2**62))
    assert a.texture_seed != draw_frame(ALL, 7, 13, ["gold"], True).texture_seed
    kept = RandomizationRanges(
        MaterialRanges(reseed_textures=False), SunRanges(), EarthRanges(), SensorRanges(),
        PoseRanges(),
    )  # fmt: skip
    b = draw_frame(kept, 7, 12, ["gold"], hand_placed=True)
    assert b.texture_seed is None and b.materials == a.materials and b.sun == a.sun
    only_sun = RandomizationRanges(None, SunRanges(), None, None, None)
    assert draw_frame(only_sun, 7, 12, [], True).texture_seed is None
    with pytest.raises(SatsightError, match="reseed_textures must be true or false"):
        MaterialRanges(reseed_textures=1)


def test_the_earth_goes_behind_the_target_at_the_stated_rate() -> None:
    """Over 4000 frames the Earth is moved behind the target at behind_probability within
    4 standard errors; the earlier draws (albedo, surface, clouds) do not change with it."""
    ranges = EarthRanges(behind_probability=0.3)
    draws = [draw_earth(ranges, 5, i) for i in range(N_FRAMES)]
    rate = np.mean([d.behind for d in draws])
    assert abs(rate - 0.3) < Z * math.sqrt(0.3 * 0.7 / N_FRAMES)
    never = draw_earth(EarthRanges(behind_probability=0.0), 5, 17)
    assert not never.behind and never.albedo_scale == draws[17].albedo_scale
