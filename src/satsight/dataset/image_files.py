"""Image file formats: 8- and 16-bit PNG (imagecodecs) and float32 OpenEXR."""

from __future__ import annotations

from pathlib import Path

import imagecodecs
import numpy as np
import OpenEXR

# zlib level of PNG files: 3 compresses mostly-black space images nearly as well as 9,
# several times faster.
PNG_ZLIB_LEVEL = 3


def write_png(path: Path, image: np.ndarray) -> None:
    """Write a uint8 or uint16 image, (H, W) grey or (H, W, 3) RGB, as PNG of that depth."""
    image = np.ascontiguousarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG holds uint8 or uint16 samples, not {image.dtype}")
    Path(path).write_bytes(imagecodecs.png_encode(image, level=PNG_ZLIB_LEVEL))


def read_png(path: Path) -> np.ndarray:
    """Read a PNG to (H, W) or (H, W, C) at its stored bit depth."""
    return imagecodecs.png_decode(Path(path).read_bytes())


def write_exr(path: Path, channels: dict[str, np.ndarray]) -> None:
    """Write float32 images to an RLE-compressed scanline OpenEXR file.

    RLE is lossless, and on space images (mostly exact zeros) it is twice as fast as ZIP
    for files about 20 % larger.

    channels: name -> (H, W) array, or an (H, W, 3) array named "RGB", which becomes the
    R, G, B channels (other 3-plane names become NAME.R, NAME.G, NAME.B).
    """
    header = {"compression": OpenEXR.RLE_COMPRESSION, "type": OpenEXR.scanlineimage}
    data = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    with OpenEXR.File(header, data) as exr:
        exr.write(str(path))


def read_exr(path: Path) -> dict[str, np.ndarray]:
    """Read an OpenEXR file to a dict of channel (group) name -> array."""
    with OpenEXR.File(str(path)) as exr:
        return {name: channel.pixels.copy() for name, channel in exr.channels().items()}
