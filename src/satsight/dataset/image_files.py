"""Image file formats: 8- and 16-bit PNG (compressed by libdeflate or zlib-ng through
imagecodecs) and float OpenEXR (float32, or half where asked, with an optional data
window)."""

from __future__ import annotations

import errno
import re
import shutil
import struct
from pathlib import Path

import imagecodecs
import numpy as np
import OpenEXR

# PNG files here are written as the PNG specification (3rd edition, W3C 2025) lays them
# out: IHDR, the image data in IDAT chunks, IEND, every row unfiltered (filter type 0).
# Measured on 4096 x 4112 space frames (2-core CPU), against libpng's encoder with zlib at
# level 1 (and, for masks, its "sub" filter and run-length strategy):
# - raw DN and previews (read noise everywhere), where row filters only add entropy:
#   libdeflate at level 1, 0.12 s against 0.26 s and 6.9 against 7.5 MB for a DN frame of
#   space, 0.29 s against 0.76 s and 27.2 against 27.6 MB for one filled by the Earth,
#   0.07 s against 0.15 s and 3.6 against 4.1 MB for a preview;
# - masks and part ids (a few hundred non-zero pixels in a frame of zeros): zlib-ng at
#   level 2, 0.003 s against 0.022 s and 16 against 24 kB for an 8-bit mask, 0.007 s
#   against 0.044 s and 33 against 40 kB for 16-bit part ids. (libdeflate takes 0.04 s
#   there; zlib-ng takes 0.20 s and 7.4 MB for the DN frame.)
PNG_NOISY_DEFLATE_LEVEL = 1  # libdeflate
PNG_SPARSE_ZLIB_NG_LEVEL = 2  # zlib-ng
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_IDAT_BYTES = 1 << 20  # image data split into chunks of at most 1 MiB
_PNG_COLOUR_TYPE = {1: 0, 3: 2}  # channels -> PNG colour type (grey, RGB)


def encode_png(image: np.ndarray, noisy: bool = False) -> bytes:
    """PNG bytes of a uint8 or uint16 image, (H, W) grey or (H, W, 3) RGB, at that depth.

    noisy: the image is noise-dominated (raw DN, its stretches), compressed by libdeflate;
    else mostly uniform (masks, ids, depth of a small target), by zlib-ng (see above).
    """
    image = np.ascontiguousarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG holds uint8 or uint16 samples, not {image.dtype}")
    height, width = image.shape[:2]
    channels = 1 if image.ndim == 2 else image.shape[2]
    if image.ndim not in (2, 3) or channels not in _PNG_COLOUR_TYPE:
        raise ValueError(f"PNG images here are (H, W) grey or (H, W, 3) RGB, not {image.shape}")
    rows = np.empty((height, 1 + width * channels * image.itemsize), np.uint8)
    rows[:, 0] = 0  # filter type 0 (none) for each row
    # Samples are big-endian in PNG.
    rows[:, 1:].view(image.dtype.newbyteorder(">")).reshape(image.shape)[...] = image
    if noisy:
        stream = imagecodecs.deflate_encode(rows, PNG_NOISY_DEFLATE_LEVEL)  # zlib format
    else:
        stream = imagecodecs.zlibng_encode(rows, PNG_SPARSE_ZLIB_NG_LEVEL)
    header = struct.pack(
        ">IIBBBBB", width, height, 8 * image.itemsize, _PNG_COLOUR_TYPE[channels], 0, 0, 0
    )
    parts = [_PNG_SIGNATURE, _png_chunk(b"IHDR", header)]
    for start in range(0, max(1, len(stream)), _PNG_IDAT_BYTES):
        parts.append(_png_chunk(b"IDAT", stream[start : start + _PNG_IDAT_BYTES]))
    parts.append(_png_chunk(b"IEND", b""))
    return b"".join(parts)


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    """A PNG chunk: length, type, data and the CRC-32 of type and data."""
    crc = imagecodecs.deflate_crc32(data, imagecodecs.deflate_crc32(kind))
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


def write_png(path: Path, image: np.ndarray, noisy: bool = False) -> None:
    """Write a uint8 or uint16 image as PNG (see ``encode_png``)."""
    Path(path).write_bytes(encode_png(image, noisy))


def read_png(path: Path) -> np.ndarray:
    """Read a PNG to (H, W) or (H, W, C) at its stored bit depth."""
    return imagecodecs.png_decode(Path(path).read_bytes())


#: Lossless OpenEXR compressions a dataset's EXR files may use (``outputs.exr_compression``)
#: and the OpenEXR version that reads them. Measured on the 4096 x 4112 radiance of a
#: frame filled by the Earth (float32 RGB, 202 MB raw), 2-core CPU, one thread: RLE 0.43 s
#: to write, 202 MB (no gain on smooth float values), 0.5 s to read; ZIP 1.1 s, 23.6 MB,
#: 0.23 s; HTJ2K (32 scanlines) 0.35 s, 10.3 MB, 0.21 s; Zstandard 0.28 s, 10.4 MB, 0.10 s.
#: On space frames the data windows leave little to compress.
EXR_COMPRESSIONS = {
    "rle": (OpenEXR.RLE_COMPRESSION, "any OpenEXR reader"),
    "zip": (OpenEXR.ZIP_COMPRESSION, "any OpenEXR reader"),
    "htj2k": (OpenEXR.HTJ2K32_COMPRESSION, "OpenEXR 3.4 or newer"),
    "zstd": (OpenEXR.ZSTD_COMPRESSION, "OpenEXR 3.5 or newer"),
}


def write_exr(
    path: Path,
    channels: dict[str, np.ndarray],
    data_window: tuple[int, int, int, int] | None = None,
    half: tuple[str, ...] = (),
    compression: str = "rle",
) -> None:
    """Write float images to a losslessly compressed scanline OpenEXR file.

    compression: a name of ``EXR_COMPRESSIONS``; RLE by default, which every reader
    opens, and which on space images (mostly exact zeros) is twice as fast as ZIP for
    files about 20 % larger.

    channels: name -> (H, W) array, or an (H, W, 3) array named "RGB", which becomes the
    R, G, B channels (other 3-plane names become NAME.R, NAME.G, NAME.B); float32 unless
    named in ``half`` (stored as 16-bit half floats). data_window: (x0, y0, x1, y1), the
    pixels x0 <= x < x1, y0 <= y < y1 that are stored (OpenEXR's data window; the display
    window stays the whole H x W image, and readers take the pixels outside as 0); None
    stores them all. An empty window stores the one pixel (0, 0).

    OpenEXR reports a failed write (a full disk among others) as a RuntimeError; it is
    raised here as an OSError naming the file, ENOSPC when the disk is (nearly) full.
    """
    if compression not in EXR_COMPRESSIONS:
        raise ValueError(f"unknown EXR compression {compression!r}; use {list(EXR_COMPRESSIONS)}")
    header = {"compression": EXR_COMPRESSIONS[compression][0], "type": OpenEXR.scanlineimage}
    height, width = next(iter(channels.values())).shape[:2]
    rows = cols = slice(None)
    if data_window is not None:
        x0, y0, x1, y1 = (int(v) for v in data_window)
        if x1 <= x0 or y1 <= y0:
            x0, y0, x1, y1 = 0, 0, 1, 1
        if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
            raise ValueError(f"data window {data_window} outside the {width} x {height} image")
        rows, cols = slice(y0, y1), slice(x0, x1)
        header["displayWindow"] = (
            np.array([0, 0], np.int32),
            np.array([width - 1, height - 1], np.int32),
        )
        header["dataWindow"] = (np.array([x0, y0], np.int32), np.array([x1 - 1, y1 - 1], np.int32))
    data = {
        k: np.ascontiguousarray(v[rows, cols], dtype=np.float16 if k in half else np.float32)
        for k, v in channels.items()
    }
    with OpenEXR.File(header, data) as exr:
        try:
            exr.write(str(path))
        except RuntimeError as error:
            raise _exr_write_error(Path(path), error) from None


def exr_channels(path: Path, separate: bool = False) -> dict[str, np.ndarray]:
    """The channels of an OpenEXR file over its whole display window, float32: pixels
    outside its data window are 0, half floats are widened. separate: one (H, W) plane per
    channel; else R, G, B grouped as "RGB" (H, W, 3), as the binding groups them."""
    with OpenEXR.File(str(path), separate_channels=separate) as exr:
        header = exr.header()  # read while the file is open
        dx0, dy0, dx1, dy1 = (int(v) for corner in header["dataWindow"] for v in corner)
        wx0, wy0, wx1, wy1 = (int(v) for corner in header["displayWindow"] for v in corner)
        stored = {name: channel.pixels for name, channel in exr.channels().items()}
    full = (dx0, dy0, dx1, dy1) == (wx0, wy0, wx1, wy1)
    out = {}
    for name, pixels in stored.items():
        pixels = np.asarray(pixels)
        if full:
            if pixels.dtype != np.float32:
                pixels = pixels.astype(np.float32)
            out[name] = pixels if pixels.flags.owndata else pixels.copy()
            continue
        plane = np.zeros((wy1 - wy0 + 1, wx1 - wx0 + 1, *pixels.shape[2:]), np.float32)
        # The data window may reach past the display window: only their overlap shows.
        ys = slice(max(dy0, wy0), min(dy1, wy1) + 1)
        xs = slice(max(dx0, wx0), min(dx1, wx1) + 1)
        plane[ys.start - wy0 : ys.stop - wy0, xs.start - wx0 : xs.stop - wx0] = pixels[
            ys.start - dy0 : ys.stop - dy0, xs.start - dx0 : xs.stop - dx0
        ]
        out[name] = plane
    return out


# Free space under which a failed EXR write is taken for a full disk (OpenEXR writes in
# blocks of a few MB and does not say why a write failed).
_NEARLY_FULL_BYTES = 64 << 20


def _exr_write_error(path: Path, error: RuntimeError) -> OSError:
    try:
        full = shutil.disk_usage(path.parent).free < _NEARLY_FULL_BYTES
    except OSError:
        full = False
    if full:
        return OSError(errno.ENOSPC, "No space left on device", str(path))
    reason = re.sub(r"( to image file)? '[^']*'", "", str(error))  # the temporary name
    return OSError(errno.EIO, f"OpenEXR could not write the file ({reason})", str(path))


def read_exr(path: Path) -> dict[str, np.ndarray]:
    """Read an OpenEXR file to a dict of channel (group) name -> float32 array over the
    whole image (``exr_channels``).

    The binding hands back arrays that own their memory, which outlive the file; one that
    does not is copied (a 4096 x 4112 RGB copy costs ~0.1 s)."""
    return exr_channels(path)
