"""Image file formats: 8- and 16-bit PNG (imagecodecs) and float32 OpenEXR."""

from __future__ import annotations

import errno
import re
import shutil
from pathlib import Path

import imagecodecs
import numpy as np
import OpenEXR

# zlib settings of PNG files, measured on 4096 x 4112 space frames (2-core CPU):
# - level 1 is 2x faster than level 3 and its files are 0-8 % larger;
# - mostly-empty images (masks, previews, part ids): the "sub" row filter with zlib's
#   run-length strategy, 4x faster than libpng's adaptive filter at equal size;
# - raw DN (read noise everywhere): no row filter, 1.7x faster than level 1 with the
#   adaptive filter, and 7 % smaller, as filters only add entropy to noise.
PNG_ZLIB_LEVEL = 1
_PNG_FILTER_NONE, _PNG_FILTER_SUB = 0x08, 0x10  # libpng's filter flags
_ZLIB_RLE_STRATEGY = 3


def encode_png(image: np.ndarray, noisy: bool = False) -> bytes:
    """PNG bytes of a uint8 or uint16 image, (H, W) grey or (H, W, 3) RGB, at that depth.

    noisy: the image is noise-dominated (raw DN): rows are stored unfiltered.
    """
    image = np.ascontiguousarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG holds uint8 or uint16 samples, not {image.dtype}")
    if noisy:
        return imagecodecs.png_encode(image, level=PNG_ZLIB_LEVEL, filter=_PNG_FILTER_NONE)
    return imagecodecs.png_encode(
        image, level=PNG_ZLIB_LEVEL, strategy=_ZLIB_RLE_STRATEGY, filter=_PNG_FILTER_SUB
    )


def write_png(path: Path, image: np.ndarray, noisy: bool = False) -> None:
    """Write a uint8 or uint16 image as PNG (see ``encode_png``)."""
    Path(path).write_bytes(encode_png(image, noisy))


def read_png(path: Path) -> np.ndarray:
    """Read a PNG to (H, W) or (H, W, C) at its stored bit depth."""
    return imagecodecs.png_decode(Path(path).read_bytes())


def write_exr(path: Path, channels: dict[str, np.ndarray]) -> None:
    """Write float32 images to an RLE-compressed scanline OpenEXR file.

    RLE is lossless, and on space images (mostly exact zeros) it is twice as fast as ZIP
    for files about 20 % larger.

    channels: name -> (H, W) array, or an (H, W, 3) array named "RGB", which becomes the
    R, G, B channels (other 3-plane names become NAME.R, NAME.G, NAME.B).

    OpenEXR reports a failed write (a full disk among others) as a RuntimeError; it is
    raised here as an OSError naming the file, ENOSPC when the disk is (nearly) full.
    """
    header = {"compression": OpenEXR.RLE_COMPRESSION, "type": OpenEXR.scanlineimage}
    data = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    with OpenEXR.File(header, data) as exr:
        try:
            exr.write(str(path))
        except RuntimeError as error:
            raise _exr_write_error(Path(path), error) from None


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
    """Read an OpenEXR file to a dict of channel (group) name -> array.

    The binding hands back arrays that own their memory, which outlive the file; one that
    does not is copied (a 4096 x 4112 RGB copy costs ~0.1 s)."""
    with OpenEXR.File(str(path)) as exr:
        return {
            name: pixels if pixels.flags.owndata else pixels.copy()
            for name, pixels in ((n, c.pixels) for n, c in exr.channels().items())
        }
