"""Preview images: max-scaled 16-bit radiance, crop windows and thumbnails."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.dataset.preview import (
    PREVIEW_GAMMA,
    crop_box_xyxy_px,
    radiance_to_uint16,
    thumbnail,
)

HALF_COUNT = 0.5


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


# --- radiance_to_uint16 -------------------------------------------------------------------
def test_maximum_maps_to_full_scale_and_scale_reproduces_radiance(rng) -> None:
    radiance = rng.uniform(0.0, 37.5, size=(41, 29, 3))
    radiance[rng.random((41, 29, 3)) < 0.4] = 0.0
    radiance[3, 5, 1] = 80.25  # the single brightest sample
    counts, scale = radiance_to_uint16(radiance)
    assert counts.dtype == np.uint16
    assert counts.shape == radiance.shape
    assert counts[3, 5, 1] == 65535
    assert np.count_nonzero(counts == 65535) == 1
    assert scale == 80.25 / 65535.0
    # Linear with rounding to nearest: |counts * scale - L| <= half a count.
    error_counts = np.abs(counts * scale - radiance) / scale
    assert error_counts.max() <= HALF_COUNT + 1e-9
    # Exact zeros stay exact zeros.
    assert np.all(counts[radiance == 0.0] == 0)


def test_known_values_round_to_nearest_count() -> None:
    radiance = np.array([[0.0, 0.25, 0.5, 1.0, 2.0]])
    counts, scale = radiance_to_uint16(radiance)
    assert scale == 2.0 / 65535.0
    # 65535 / 8 = 8191.875 -> 8192, 65535 / 4 = 16383.75 -> 16384, 65535 / 2 = 32767.5 -> 32768
    np.testing.assert_array_equal(counts, [[0, 8192, 16384, 32768, 65535]])


def test_float32_radiance_keeps_its_scale(rng) -> None:
    radiance = rng.uniform(0.0, 5.0, size=(16, 16, 3)).astype(np.float32)
    counts, scale = radiance_to_uint16(radiance)
    assert scale == float(radiance.max()) / 65535.0
    assert counts.max() == 65535
    # float32 arithmetic adds well under 0.01 count of rounding to the half count.
    assert (np.abs(counts * scale - radiance) / scale).max() <= HALF_COUNT + 0.01


def test_negative_values_clip_to_zero() -> None:
    counts, scale = radiance_to_uint16(np.array([-1.0, 0.5, 1.0]))
    np.testing.assert_array_equal(counts, [0, 32768, 65535])
    assert scale == 1.0 / 65535.0


@pytest.mark.parametrize("shape", [(12, 9, 3), (0, 4, 3)], ids=["black", "empty"])
def test_black_frame_gives_zeros_and_zero_scale(shape) -> None:
    counts, scale = radiance_to_uint16(np.zeros(shape, dtype=np.float32))
    assert scale == 0.0
    assert counts.dtype == np.uint16
    assert counts.shape == shape
    assert not counts.any()


# --- crop_box_xyxy_px ----------------------------------------------------------------------
def test_whole_image_without_a_box() -> None:
    assert crop_box_xyxy_px(None, (4112, 4096)) == (0, 0, 4096, 4112)


def test_small_box_gets_the_minimum_side_grown_by_the_margin() -> None:
    # side = ceil(64 * (1 + 2 * 0.4)) = 116, centred on (105, 205).
    assert crop_box_xyxy_px([100, 200, 109, 209], (4112, 4096)) == (47, 147, 163, 263)


def test_large_box_grows_by_the_margin() -> None:
    # 201 x 101 px box: side = ceil(201 * 1.8) = 362, centre (1100, 600).
    x0, y0, x1, y1 = crop_box_xyxy_px([1000, 550, 1200, 650], (4112, 4096))
    assert (x1 - x0, y1 - y0) == (362, 362)
    assert (x0, y0) == (1100 - 181, 600 - 181)


def test_box_in_a_corner_is_clipped_to_the_image() -> None:
    assert crop_box_xyxy_px([0, 0, 9, 9], (100, 200)) == (0, 0, 100, 100)
    assert crop_box_xyxy_px([190, 90, 199, 99], (100, 200)) == (100, 0, 200, 100)


def test_crop_contains_box_is_square_and_inside_image(rng) -> None:
    for _ in range(3000):
        height, width = (int(v) for v in rng.integers(1, 400, size=2))
        limit = min(height, width)
        bw, bh = (int(v) for v in rng.integers(1, limit + 1, size=2))
        x0 = int(rng.integers(0, width - bw + 1))
        y0 = int(rng.integers(0, height - bh + 1))
        box = [x0, y0, x0 + bw - 1, y0 + bh - 1]
        margin = float(rng.choice([0.0, 0.1, 0.4, 1.0]))
        min_side = int(rng.choice([1, 16, 64]))
        left, top, right, bottom = crop_box_xyxy_px(box, (height, width), margin, min_side)
        case = (box, (height, width), margin, min_side)
        assert right - left == bottom - top, case
        assert 0 <= left and right <= width and 0 <= top and bottom <= height, case
        assert left <= box[0] and box[2] < right, case
        assert top <= box[1] and box[3] < bottom, case
        wanted = math.ceil(max(bw, bh, min_side) * (1.0 + 2.0 * margin))
        assert right - left == min(wanted, width, height), case


# --- thumbnail -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("shape", "max_side_px", "expected_shape"),
    [
        ((1030, 700, 3), 512, (343, 233, 3)),
        ((4112, 4096, 3), 512, (456, 455, 3)),
        ((300, 200, 3), 512, (300, 200, 3)),
        ((64, 64, 3), 16, (16, 16, 3)),
    ],
)
def test_thumbnail_is_no_larger_than_asked(shape, max_side_px, expected_shape) -> None:
    image = np.zeros(shape, dtype=np.float32)
    image[shape[0] // 2, shape[1] // 3] = (3.0, 2.0, 1.0)
    small = thumbnail(image, max_side_px)
    assert small.shape == expected_shape
    assert max(small.shape[:2]) <= max_side_px
    assert small.min() >= 0.0
    assert small.max() == pytest.approx(1.0, abs=1e-6)


def test_thumbnail_box_averages_then_gamma_stretches() -> None:
    image = np.zeros((4, 4, 3))
    image[0, 0] = 4.0  # top-left block mean 1
    image[2:4, 2:4] = (2.0, 1.0, 0.5)  # bottom-right block means (2, 1, 0.5)
    small = thumbnail(image, max_side_px=2)
    assert small.shape == (2, 2, 3)
    g = 1.0 / PREVIEW_GAMMA
    expected = np.zeros((2, 2, 3))
    expected[0, 0] = 0.5**g
    expected[1, 1] = (1.0, 0.5**g, 0.25**g)
    np.testing.assert_allclose(small, expected, rtol=1e-12, atol=0)


def test_thumbnail_of_a_black_frame_is_black() -> None:
    small = thumbnail(np.zeros((100, 60, 3)), max_side_px=32)
    assert small.shape == (25, 15, 3)
    assert not small.any()


def test_thumbnail_range_is_zero_to_one(rng) -> None:
    image = rng.exponential(50.0, size=(257, 130, 3))
    small = thumbnail(image, max_side_px=64)
    assert small.shape == (51, 26, 3)  # step ceil(257 / 64) = 5
    assert small.min() >= 0.0 and small.max() <= 1.0
    assert small.max() == 1.0
