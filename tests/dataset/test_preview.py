"""Preview images: the 8-bit DN stretch, crop windows and thumbnails."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.dataset.preview import (
    PREVIEW_GAMMA,
    crop_box_xyxy_px,
    dn_preview_uint8,
    thumbnail,
)
from satsight.errors import SatsightError


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)


# --- dn_preview_uint8 ----------------------------------------------------------------------
def test_preview_is_black_at_bias_white_at_full_well_gamma_between() -> None:
    bias, full = 1000.0, 61000.0
    dn = np.array([[0, 999, 1000, 16000, 31000, 61000, 65535]], dtype=np.uint16)
    preview = dn_preview_uint8(dn, bias, full)
    assert preview.dtype == np.uint8
    expected = [
        0,
        0,
        0,
        round(255 * 0.25 ** (1 / PREVIEW_GAMMA)),
        round(255 * 0.5 ** (1 / PREVIEW_GAMMA)),
        255,
        255,
    ]
    np.testing.assert_array_equal(preview[0], expected)


def test_preview_is_monotonic_in_dn(rng) -> None:
    dn = np.sort(rng.integers(0, 65536, size=5000)).astype(np.uint16)
    preview = dn_preview_uint8(dn, 1000.0, 61000.0)
    assert np.all(np.diff(preview.astype(int)) >= 0)


def test_preview_needs_full_well_above_bias() -> None:
    with pytest.raises(SatsightError, match="must exceed bias_dn"):
        dn_preview_uint8(np.zeros((2, 2), np.uint16), 1000.0, 1000.0)


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
