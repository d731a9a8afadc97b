"""PNG and OpenEXR files: bit-exact round trips at the stored depth."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import imagecodecs
import numpy as np
import pytest
from PIL import Image

from satsight.dataset.image_files import (
    EXR_COMPRESSIONS,
    encode_png,
    read_exr,
    read_png,
    write_exr,
    write_png,
)

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


@pytest.mark.parametrize("noisy", [True, False], ids=["libdeflate", "zlib-ng"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [SHAPE, (*SHAPE, 3), (1, 1)], ids=["grey", "rgb", "one"])
def test_png_is_read_back_by_libpng_and_pillow(rng, dtype, shape, noisy) -> None:
    """The encoder writes its own chunks around libdeflate's or zlib-ng's stream: libpng
    (which checks every chunk's CRC and the zlib checksum) and Pillow read the same
    samples, noise or a sparse mask."""
    info = np.iinfo(dtype)
    image = rng.integers(0, info.max, size=shape, dtype=dtype, endpoint=True)
    if not noisy:  # a few values in zeros
        image[rng.uniform(size=shape) < 0.97] = 0
    image.flat[0] = info.max
    data = encode_png(image, noisy=noisy)
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    np.testing.assert_array_equal(imagecodecs.png_decode(data), image)
    if not (dtype == np.uint16 and len(shape) == 3):  # Pillow has no 16-bit RGB mode
        np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(data))), image)
    # A flipped bit in the image data is caught (deflate stream, zlib or chunk checksum).
    broken = bytearray(data)
    broken[data.index(b"IDAT") + 6] ^= 0x01
    with pytest.raises(imagecodecs.PngError):
        imagecodecs.png_decode(bytes(broken))


def test_noisy_png_splits_its_data_into_idat_chunks_of_a_mebibyte(rng) -> None:
    image = rng.integers(0, 65535, size=(600, 1000), dtype=np.uint16, endpoint=True)
    data = encode_png(image, noisy=True)
    kinds, sizes, at = [], [], 8
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kinds.append(data[at + 4 : at + 8])
        sizes.append(length)
        at += 12 + length
    assert at == len(data)
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND"
    idat = [size for kind, size in zip(kinds, sizes, strict=True) if kind == b"IDAT"]
    assert len(idat) == 2 and idat[0] == 1 << 20  # 1.2 MB of noise: two chunks
    np.testing.assert_array_equal(imagecodecs.png_decode(data), image)


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


@pytest.mark.parametrize("compression", sorted(EXR_COMPRESSIONS))
def test_every_exr_compression_is_lossless(tmp_path: Path, rng, compression) -> None:
    """float32 (zeros of both signs, subnormals, the largest value) and half channels, over
    a data window, come back bit for bit, and the file's header names the compression."""
    import OpenEXR

    rgb = _float_image(rng, (*SHAPE, 3))
    rgb.flat[-4] = 1e-42  # subnormal
    normals = rng.uniform(-1.0, 1.0, size=SHAPE).astype(np.float32)
    path = tmp_path / f"{compression}.exr"
    window = (3, 2, SHAPE[1] - 1, SHAPE[0] - 4)
    write_exr(path, {"RGB": rgb, "X": normals}, window, half=("X",), compression=compression)
    back = read_exr(path)
    x0, y0, x1, y1 = window
    inside = np.zeros(SHAPE, dtype=bool)
    inside[y0:y1, x0:x1] = True
    expected = np.where(inside[..., None], rgb, np.float32(0.0))
    np.testing.assert_array_equal(back["RGB"].view(np.uint32), expected.view(np.uint32))
    halves = np.where(inside, normals.astype(np.float16).astype(np.float32), np.float32(0.0))
    np.testing.assert_array_equal(back["X"], halves)
    with OpenEXR.File(str(path), header_only=True) as exr:
        assert exr.header()["compression"] == EXR_COMPRESSIONS[compression][0]
    with pytest.raises(ValueError, match="unknown EXR compression"):
        write_exr(tmp_path / "bad.exr", {"X": normals}, compression="piz")


def test_a_data_window_stores_only_its_pixels_and_reads_back_whole(tmp_path: Path, rng) -> None:
    """Pixels inside the window come back bit-exact, those outside as 0, over the whole
    image; the file holds the window alone (OpenEXR's header names it, the display window
    stays the image), so a window over a few pixels makes a file of a few hundred bytes."""
    import OpenEXR

    from satsight.dataset.frame_files import nonzero_window

    depth = np.zeros(SHAPE, dtype=np.float32)
    depth[5:9, 20:31] = rng.uniform(10.0, 20.0, size=(4, 11))
    window = nonzero_window(depth)
    assert window == (20, 5, 31, 9)
    write_exr(tmp_path / "d.exr", {"Z": depth}, window)
    write_exr(tmp_path / "full.exr", {"Z": depth})
    np.testing.assert_array_equal(read_exr(tmp_path / "d.exr")["Z"], depth)
    with OpenEXR.File(str(tmp_path / "d.exr"), header_only=True) as exr:
        low, high = exr.header()["dataWindow"]
        assert low.tolist() == [20, 5] and high.tolist() == [30, 8]
        low, high = exr.header()["displayWindow"]
        assert low.tolist() == [0, 0] and high.tolist() == [SHAPE[1] - 1, SHAPE[0] - 1]
    assert (tmp_path / "d.exr").stat().st_size < (tmp_path / "full.exr").stat().st_size
    # No surface at all: one stored pixel, still the whole image when read.
    empty = np.zeros(SHAPE, dtype=np.float32)
    assert nonzero_window(empty) == (0, 0, 0, 0)
    write_exr(tmp_path / "e.exr", {"Z": empty}, (0, 0, 0, 0))
    np.testing.assert_array_equal(read_exr(tmp_path / "e.exr")["Z"], empty)
    with pytest.raises(ValueError, match="outside"):
        write_exr(tmp_path / "bad.exr", {"Z": depth}, (0, 0, SHAPE[1] + 1, 2))


def test_the_nonzero_window_holds_every_pixel_with_a_value_in_any_channel() -> None:
    """The radiance window: a value in one channel of one pixel counts, -0.0 too (its bits
    are not 0, and the file keeps it), +0.0 does not."""
    from satsight.dataset.frame_files import nonzero_window

    rgb = np.zeros((*SHAPE, 3), dtype=np.float32)
    assert nonzero_window(rgb) == (0, 0, 0, 0)
    rgb[7, 40, 1] = 1e-30  # green only, tiny
    assert nonzero_window(rgb) == (40, 7, 41, 8)
    rgb[30, 3, 2] = -0.0
    assert nonzero_window(rgb) == (3, 7, 41, 31)
    rgb[30, 3, 2] = 0.0
    assert nonzero_window(rgb) == (40, 7, 41, 8)
    parts = np.zeros(SHAPE, dtype=np.uint16)
    parts[0, SHAPE[1] - 1] = 1
    parts[SHAPE[0] - 1, 0] = 2
    assert nonzero_window(parts) == (0, 0, SHAPE[1], SHAPE[0])


def test_half_float_channels_keep_unit_normals_to_half_precision(tmp_path: Path, rng) -> None:
    """Channels stored as half floats round each value to 11 significant bits: a unit
    normal's components come back within 2^-11 relative (half an ulp is 2^-11 of the
    value's power of two), its length within 1e-3 of 1 (the validator's tolerance), as
    float32."""
    n = rng.normal(size=(*SHAPE, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    planes = {c: n[..., k].astype(np.float32) for k, c in enumerate("XYZ")}
    write_exr(tmp_path / "n.exr", planes, half=("X", "Y", "Z"))
    back = read_exr(tmp_path / "n.exr")
    for k, c in enumerate("XYZ"):
        assert back[c].dtype == np.float32
        np.testing.assert_allclose(back[c], n[..., k], rtol=2.0**-11, atol=2.0**-25)
    length = np.sqrt(sum(back[c].astype(np.float64) ** 2 for c in "XYZ"))
    assert np.abs(length - 1).max() < 1e-3
    full = tmp_path / "f.exr"
    write_exr(full, planes)
    assert (tmp_path / "n.exr").stat().st_size < full.stat().st_size
