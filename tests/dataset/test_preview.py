"""Preview images: the 8-bit DN stretch, crop windows and thumbnails."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from satsight.dataset.preview import (
    CONTACT_CELL_PX,
    DEFAULT_ASINH_SOFTENING_DN,
    DN_PREVIEW_STRETCH,
    PREVIEW_GAMMA,
    PreviewStretch,
    crop_box_xyxy_px,
    dn_preview_asinh_uint8,
    dn_preview_uint8,
    thumbnail,
    write_contact_sheet,
)
from satsight.errors import SatsightError
from satsight.sensor.detector import DetectorParameters


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


# The gamma stretch of every DN code, as released before the stretch became a choice:
# SHA-256 of the (256, 256) uint8 image of DN 0 ... 65535 for (bias_dn, full_well_dn).
GAMMA_LUT_SHA256 = {
    (1000.0, 61000.0): "e01c0b5e2e6082cd40564cb752686d7dc7424a12bed9f392f4e5818928ad99d9",
    (1000.0, 1000.0 + 350000 / 5.833): (
        "1a4a8c89e48f978d3a247b59530b09d96b99184d4ec928cc2a378761fb63624d"
    ),
    (0.0, 65535.0): "22fb0743bbf2af07123155d27ea8b82a64cf5232cb68d18b9aed3ebb1986b53d",
}


@pytest.mark.parametrize(("bias", "full_well"), list(GAMMA_LUT_SHA256))
def test_gamma_stretch_is_byte_identical_to_the_released_one(bias, full_well) -> None:
    every_code = np.arange(65536, dtype=np.uint16).reshape(256, 256)
    for image in (
        dn_preview_uint8(every_code, bias, full_well),
        PreviewStretch("gamma").apply(every_code, bias, full_well),
    ):
        digest = hashlib.sha256(image.tobytes()).hexdigest()
        assert digest == GAMMA_LUT_SHA256[(bias, full_well)]


def _star_and_target_frame(rng: np.random.Generator, star_peak_e: float):
    """A 96 x 96 DN frame of the default detector: read noise everywhere, a star (Gaussian,
    sigma 0.7 px, peak ``star_peak_e`` electrons) at (20, 20) and a target whose signal
    rises linearly from 20 % to 100 % of full well along x over columns 40-87, rows 40-79.
    Returns (dn, detector, the target's noiseless signal in electrons (96, 96))."""
    detector = DetectorParameters()
    y, x = np.mgrid[0:96, 0:96].astype(np.float64)
    signal_e = star_peak_e * np.exp(-((x - 20.0) ** 2 + (y - 20.0) ** 2) / (2 * 0.7**2))
    target_e = np.zeros_like(signal_e)
    ramp = np.linspace(0.2, 1.0, 48) * detector.full_well_e
    target_e[40:80, 40:88] = ramp[None, :]
    signal_e += target_e
    electrons = signal_e + rng.normal(0.0, detector.read_noise_e, signal_e.shape)
    dn = np.rint(detector.bias_dn + electrons / detector.conversion_gain_e_per_dn)
    dn = np.clip(dn, 0, detector.adc_max_dn).astype(np.uint16)
    return dn, detector, target_e


def test_asinh_shows_a_faint_star_and_keeps_the_targets_bright_end(rng) -> None:
    """A star 300 e- above the bias at its peak (60 read-noise sigma, 51 DN) reaches at least
    64/255 with the asinh stretch (76 expected: 255 asinh(51.4 / 5) / asinh(60003 / 5)),
    where the gamma stretch leaves it at 10/255; the target's bright end (>= 90 % of full
    well) shows at 250 or more, and only at full well at 255 (not clipped below it); the
    read noise stays in the darkest levels (99th percentile of the sky <= 16/255)."""
    dn, detector, target_e = _star_and_target_frame(rng, star_peak_e=300.0)
    bias, full_well = detector.bias_dn, detector.full_well_dn
    asinh = dn_preview_asinh_uint8(dn, bias, full_well)
    gamma = dn_preview_uint8(dn, bias, full_well)
    star_level = 255 * math.asinh(300 / detector.conversion_gain_e_per_dn / 5.0)
    star_level /= math.asinh((full_well - bias) / 5.0)
    assert asinh[20, 20] >= 64 and abs(int(asinh[20, 20]) - star_level) <= 6
    assert gamma[20, 20] <= 15  # the problem the asinh stretch solves
    bright = target_e >= 0.9 * detector.full_well_e
    assert asinh[bright].min() >= 250
    below_full = (target_e > 0) & (target_e <= 0.97 * detector.full_well_e)
    assert asinh[below_full].max() < 255
    assert np.all(np.diff(asinh[60, 40:88].astype(int)) >= -1)  # rises with the ramp
    sky = np.ones(dn.shape, dtype=bool)
    sky[10:31, 10:31] = False
    sky[40:80, 40:88] = False
    assert np.percentile(asinh[sky], 99) <= 16
    assert asinh[sky].mean() < 3.0


def test_asinh_stretch_closed_form_and_monotonic(rng) -> None:
    bias, full, beta = 1000.0, 61000.0, 5.0
    dn = np.array([[0, 1000, 1005, 1050, 31000, 61000, 65535]], dtype=np.uint16)
    span = full - bias
    expected = [0, 0] + [
        round(255 * math.asinh(x / beta) / math.asinh(span / beta)) for x in (5, 50, 30000)
    ]
    expected += [255, 255]
    np.testing.assert_array_equal(dn_preview_asinh_uint8(dn, bias, full, beta)[0], expected)
    codes = np.sort(rng.integers(0, 65536, size=5000)).astype(np.uint16)
    assert np.all(np.diff(dn_preview_asinh_uint8(codes, bias, full).astype(int)) >= 0)
    with pytest.raises(SatsightError, match="positive number of DN"):
        dn_preview_asinh_uint8(dn, bias, full, 0.0)
    with pytest.raises(SatsightError, match="must exceed bias_dn"):
        dn_preview_asinh_uint8(dn, bias, bias)


def test_labels_name_the_stretch() -> None:
    assert PreviewStretch() == PreviewStretch("asinh", DEFAULT_ASINH_SOFTENING_DN)
    stretch = PreviewStretch("asinh", 8.0)
    header = stretch.header()
    assert header["stretch"] == "asinh" and header["softening_dn"] == 8.0
    assert "asinh(x / 8)" in header["formula"]
    assert PreviewStretch.from_header(header) == stretch
    gamma = PreviewStretch("gamma")
    assert gamma.header() == {"stretch": "gamma", "formula": DN_PREVIEW_STRETCH, "gamma": 2.2}
    assert PreviewStretch.from_header(gamma.header()).name == "gamma"
    # Datasets written before the choice hold only the gamma formula.
    assert PreviewStretch.from_header({"stretch": DN_PREVIEW_STRETCH}).name == "gamma"
    assert PreviewStretch.from_header(None).name == "gamma"
    with pytest.raises(SatsightError, match="unknown preview stretch"):
        PreviewStretch("log")  # type: ignore[arg-type]


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


@pytest.mark.parametrize(("count", "cols"), [(1, 1), (5, 3), (10, 6)])
def test_contact_sheet_places_every_thumbnail_in_its_cell_with_a_caption(tmp_path, count, cols):
    """Each thumbnail a flat grey (its own level) with one white pixel: the sheet is
    CONTACT_CELL_PX per cell, each cell shows its grey over a whole block of pixels and
    the white pixel enlarged to a square, and the caption band above the image has ink."""
    from PIL import Image

    levels = np.linspace(0.1, 0.6, count)
    thumbnails = []
    for level in levels:
        image = np.full((24, 32), level)
        image[5, 7] = 1.0
        thumbnails.append(image)
    path = tmp_path / "sheet.png"
    write_contact_sheet(path, thumbnails, [f"#{i}\nline two" for i in range(count)], "heading")
    rows = -(-count // cols)
    cell_w, cell_h = CONTACT_CELL_PX
    with Image.open(path) as image:
        sheet = np.asarray(image.convert("L"))
    assert sheet.shape == (rows * cell_h, cols * cell_w)
    assert sheet[:10].min() == 255 and (sheet[:40] < 128).any()  # the heading's ink
    for index, level in enumerate(levels):
        row, col = divmod(index, cols)
        cell = sheet[row * cell_h : (row + 1) * cell_h, col * cell_w : (col + 1) * cell_w]
        grey = round(255 * level)
        # The thumbnail's rows and columns: full of its grey (anti-aliased caption ink may
        # hit the level in a few scattered pixels, never along a whole row).
        flat = cell == grey
        ys = np.nonzero(flat.sum(axis=1) > 16)[0]
        xs = np.nonzero(flat.sum(axis=0) > 12)[0]
        assert ys.size and xs.size, index
        scale = (xs.max() - xs.min() + 1) / 32
        assert scale == int(scale) and scale >= 2 and (ys.max() - ys.min() + 1) == 24 * scale
        block = cell[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
        white = np.argwhere(block == 255)
        assert len(white) == scale**2 and tuple(white.min(axis=0)) == (5 * scale, 7 * scale)
        assert (cell[: ys.min()] < 128).any()  # the caption above it


@pytest.mark.parametrize("key", ["dn_png16", "preview_png8"])
@pytest.mark.parametrize("bbox", [None, [40, 30, 52, 47], [0, 0, 3, 5], [300, 200, 319, 239]])
def test_a_kept_thumbnail_is_the_one_made_from_the_whole_frame(tmp_path, rng, key, bbox):
    """Thumbnails are cut to their window before any conversion or stretch: the same bits as
    converting and stretching the whole frame first."""
    from satsight.dataset.contact_sheet import _cache_path, frame_thumbnail, keep_thumbnail

    bias, full_well = 100.0, 60000.0
    dn = rng.integers(90, 65535, size=(240, 320), dtype=np.uint16)
    stretch = PreviewStretch("asinh", 40.0)
    whole = dn if key == "dn_png16" else stretch.apply(dn, bias, full_well)
    image = whole.astype(np.float32)
    if key == "dn_png16":
        image = np.clip(image - np.float32(bias), 0.0, None)
    x0, y0, x1, y1 = crop_box_xyxy_px(bbox, image.shape)
    expected = thumbnail(image[y0:y1, x0:x1, None], max_side_px=256)[..., 0]
    np.testing.assert_array_equal(frame_thumbnail(whole, key, bbox, bias), expected)
    record = {"frame_index": 3, "files": {key: "x.png"}, "bbox_xyxy_px": bbox}
    keep_thumbnail(tmp_path, record, dn, bias, full_well, stretch)
    np.testing.assert_array_equal(np.load(_cache_path(tmp_path, 3)), expected)
