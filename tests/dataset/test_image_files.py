"""PNG and OpenEXR files: bit-exact round trips at the stored depth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from satsight.dataset.image_files import read_exr, read_png, write_exr, write_png

SHAPE = (37, 53)  # odd sizes catch row-stride mistakes


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("channels", [None, 3], ids=["grey", "rgb"])
def test_png_round_trip_is_bit_exact(tmp_path: Path, rng, dtype, channels) -> None:
    shape = SHAPE if channels is None else (*SHAPE, channels)
    info = np.iinfo(dtype)
    image = rng.integers(0, info.max, size=shape, dtype=dtype, endpoint=True)
    image.flat[0], image.flat[-1] = info.min, info.max  # both ends of the range
    path = tmp_path / "image.png"
    write_png(path, image)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    back = read_png(path)
    assert back.dtype == dtype
    assert back.shape == shape
    np.testing.assert_array_equal(back, image)


def test_png_accepts_non_contiguous_views(tmp_path: Path, rng) -> None:
    image = rng.integers(0, 65535, size=(20, 30, 3), dtype=np.uint16)
    view = image[::2, ::3]
    write_png(tmp_path / "view.png", view)
    np.testing.assert_array_equal(read_png(tmp_path / "view.png"), view)


@pytest.mark.parametrize("dtype", [np.float32, np.int32, np.int16, bool])
def test_png_rejects_other_dtypes(tmp_path: Path, dtype) -> None:
    path = tmp_path / "bad.png"
    with pytest.raises(TypeError, match="uint8 or uint16"):
        write_png(path, np.zeros(SHAPE, dtype=dtype))
    assert not path.exists()


def _float_image(rng, shape) -> np.ndarray:
    """float32 values of widely different magnitudes, exact zeros, and the extremes."""
    values = (rng.standard_normal(shape) * 10.0 ** rng.integers(-8, 8, size=shape)).astype(
        np.float32
    )
    values.flat[: values.size // 3] = 0.0
    values.flat[-1] = np.finfo(np.float32).max
    values.flat[-2] = np.finfo(np.float32).tiny
    values.flat[-3] = -0.0
    return values


@pytest.mark.parametrize(
    ("name", "shape", "expected_names"),
    [
        ("RGB", (*SHAPE, 3), {"RGB"}),
        ("XYZ", (*SHAPE, 3), {"XYZ"}),
        ("Z", SHAPE, {"Z"}),
    ],
)
def test_exr_round_trip_is_bit_exact(tmp_path: Path, rng, name, shape, expected_names) -> None:
    image = _float_image(rng, shape)
    path = tmp_path / f"{name}.exr"
    write_exr(path, {name: image})
    assert path.read_bytes()[:4] == b"\x76\x2f\x31\x01"  # OpenEXR magic number
    back = read_exr(path)
    assert set(back) == expected_names
    assert back[name].dtype == np.float32
    assert back[name].shape == shape
    # Bit-exact, including the sign of zero.
    np.testing.assert_array_equal(back[name].view(np.uint32), image.view(np.uint32))


def test_exr_converts_float64_to_float32(tmp_path: Path, rng) -> None:
    depth = rng.uniform(100.0, 2e5, size=SHAPE)
    write_exr(tmp_path / "depth.exr", {"Z": depth})
    back = read_exr(tmp_path / "depth.exr")["Z"]
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, depth.astype(np.float32))


def test_exr_holds_several_channel_groups(tmp_path: Path, rng) -> None:
    rgb = _float_image(rng, (*SHAPE, 3))
    z = _float_image(rng, SHAPE)
    write_exr(tmp_path / "both.exr", {"RGB": rgb, "Z": z})
    back = read_exr(tmp_path / "both.exr")
    assert set(back) == {"RGB", "Z"}
    np.testing.assert_array_equal(back["RGB"].view(np.uint32), rgb.view(np.uint32))
    np.testing.assert_array_equal(back["Z"].view(np.uint32), z.view(np.uint32))
