"""The focal-plane irradiance of a window around the target, and the auto exposure read
from it (``SensorChain.still_exposure``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from satsight.render.buffers import mask_box
from satsight.sensor.exposure_rule import ExposureRule
from satsight.sensor.focal_plane import BLUR_REACH_RADII, grid_shape, window_around
from sensor_frames import radiance_image, sensor_chain, with_ring

#: Frame size (W, H) large enough that a small target's window is a small part of it.
SIZE_PX = (400, 360)


def _scene(m: int, rng: np.random.Generator) -> np.ndarray:
    """(H + 2m, W + 2m, 3) radiance: a speckled target (bright lone pixels, whose blur dips
    below 0 and is filled from its neighbours) near the frame's left edge, bright speckles
    one to three kernel radii beyond its box (light outside its mask), and a bright strip
    across the ring and the frame's right part, far from it."""
    w, h = SIZE_PX
    scene = np.zeros((h + 2 * m, w + 2 * m, 3), np.float32)
    near = (slice(m + 150 - 3 * m, m + 180 + 3 * m), slice(0, m + 28 + 3 * m))
    shape = scene[near].shape[:2]
    speckles = rng.random(shape) < 0.02
    scene[near][speckles] = rng.uniform(100.0, 2000.0, (int(speckles.sum()), 1))
    target = rng.uniform(0.0, 40.0, (30, 24, 3)).astype(np.float32)
    target[rng.random((30, 24)) < 0.7] = 0.0  # lone speckles
    target[5, 7] = 4000.0  # a glint
    scene[m + 150 - m : m + 180 + m, m + 4 - m : m + 28 + m] = 0.0  # none within a radius
    scene[m + 150 : m + 180, m + 4 : m + 28] = target
    scene[:, m + 300 :] = 15.0  # the Earth's limb, over the ring too
    return scene


def _target_image(m: int, seed: int = 5):
    scene = _scene(m, np.random.default_rng(seed))
    image = with_ring(scene, m)
    w, h = SIZE_PX
    part = np.zeros((h, w), np.uint16)
    part[150:180, 4:28] = 1  # the target's box is its mask (speckles and gaps alike)
    return dataclasses.replace(image, part_id=part)


def test_a_window_reads_the_whole_frames_irradiance_within_its_reach() -> None:
    chain = sensor_chain(size_px=SIZE_PX)
    m = chain.margin_px
    image = _target_image(m)
    box = mask_box(image.object_mask)
    reach = BLUR_REACH_RADII * m
    window = window_around(image, box, reach)
    assert window is not None
    g0, g1, k0, k1 = window
    assert (g0, k0) == (box[0].start + m - reach, 0)  # cut at the grid's left edge
    assert (g1, k1) == (box[0].stop + m + reach, box[1].stop + m + reach)
    whole = chain.focal_plane_irradiance_w_m2(image)
    near = chain.focal_plane_irradiance_w_m2(image, window)
    assert near.shape == whole.shape
    # Pixels outside the window read 0; the strip's light is not made at all.
    inside = np.zeros(whole.shape, bool)
    inside[max(g0 - m, 0) : g1 - m, max(k0 - m, 0) : k1 - m] = True
    assert not near[~inside].any() and whole[~inside].any()
    # Within the reach: the whole frame's values, to the FFT's round-off (float32, ~1e-7
    # of the peak; measured 6.5e-8 over three scenes). The glint is both images' peak, so
    # dips are clipped alike. Bound 2.5e-7 of the peak: a window of two radii misses light
    # that reaches the box through the negative-lobe filling (3.9-5.8e-7 measured), one
    # radius misses much more.
    peak = float(whole.max())
    assert near[box].min() >= 0.0
    np.testing.assert_allclose(near[box], whole[box], rtol=0, atol=2.5e-7 * peak)
    inner = (slice(g0 - m + reach, g1 - m - reach), slice(0, k1 - m - reach))
    np.testing.assert_allclose(near[inner], whole[inner], rtol=0, atol=2.5e-7 * peak)
    short = chain.focal_plane_irradiance_w_m2(image, window_around(image, box, m))
    assert np.abs(short[box] - whole[box]).max() > 1e-3 * peak


def test_the_still_exposure_is_the_whole_frames_and_the_same_either_way() -> None:
    chain = sensor_chain(ExposureRule(percentile=99.0, fill_fraction=0.7), size_px=SIZE_PX)
    image = _target_image(chain.margin_px)
    whole = chain.focal_plane_irradiance_w_m2(image)
    t_whole = chain.exposure_time_s(whole, image.object_mask)
    t, made = chain.still_exposure(image)
    assert made is None  # a small target: only its window was made
    # The percentile of irradiances equal to 2.5e-7 of the peak (above): a time within
    # 2.5e-7 x peak / level of the whole frame's, the glint being 39 times the level (the
    # 99th percentile) here: 1e-5 (measured 0-7e-7 over three scenes).
    assert t == pytest.approx(t_whole, rel=1e-5)
    assert chain.still_exposure(image, whole) == (t, None)  # the same time, given or not
    assert chain.exposure.min_time_s < t < chain.exposure.max_time_s  # not at a clip


def test_a_large_target_makes_the_whole_frame_once() -> None:
    chain = sensor_chain(size_px=SIZE_PX)
    m = chain.margin_px
    scene = np.zeros((SIZE_PX[1] + 2 * m, SIZE_PX[0] + 2 * m, 3), np.float32)
    scene[m + 20 : m + 340, m + 30 : m + 380] = 12.0
    image = with_ring(scene, m)
    assert window_around(image, mask_box(image.object_mask), 3 * m) is None
    whole = chain.focal_plane_irradiance_w_m2(image)
    t, made = chain.still_exposure(image)
    np.testing.assert_array_equal(made, whole)
    assert t == chain.exposure_time_s(whole, image.object_mask)
    t_given, given = chain.still_exposure(image, whole)
    assert t_given == t and given is whole


def test_windows_cover_the_grid_cut_at_its_edges() -> None:
    chain = sensor_chain(size_px=SIZE_PX)
    m = chain.margin_px
    image = _target_image(m)
    gh, gw = grid_shape(image)
    assert (gh, gw) == (SIZE_PX[1] + 2 * m, SIZE_PX[0] + 2 * m)
    assert window_around(image, None, 60) is None  # no target: the whole grid
    corner = (slice(0, 3), slice(SIZE_PX[0] - 2, SIZE_PX[0]))
    # Reach 30 beyond a ring of m = 20: cut at the grid's top and right edges.
    assert m == 20
    assert window_around(image, corner, 30) == (0, 53, SIZE_PX[0] - 2 + m - 30, gw)
    # A frame without a ring: the grid is the frame.
    bare = radiance_image(np.zeros((SIZE_PX[1], SIZE_PX[0], 3), np.float32))
    assert grid_shape(bare) == (SIZE_PX[1], SIZE_PX[0])
    assert window_around(bare, (slice(100, 110), slice(5, 9)), 20) == (80, 130, 0, 29)


def test_a_fixed_exposure_carries_the_exposure_factor() -> None:
    # A randomised frame scales the rule's time by its exposure factor, the fixed time too;
    # the motion over the exposure is found for that time (``FrameEngine.exposure_motion``).
    chain = dataclasses.replace(
        sensor_chain(ExposureRule(mode="fixed", time_s=0.25), size_px=SIZE_PX),
        exposure_factor=2.0,
    )
    image = _target_image(chain.margin_px)
    assert chain.longest_exposure_s == 0.5
    assert chain.still_exposure(image) == (0.5, None)
    auto = sensor_chain(ExposureRule(max_time_s=0.8), size_px=SIZE_PX)
    assert auto.longest_exposure_s == 0.8
