"""Image file formats: 16-bit PNG (pypng), 8-bit PNG (Pillow) and float32 OpenEXR."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenEXR
import png
from PIL import Image


def write_png16(path: Path, image: np.ndarray) -> None:
    """Write a uint16 image, (H, W) grey or (H, W, 3) RGB, as a 16-bit PNG."""
    image = np.ascontiguousarray(image, dtype=np.uint16)
    height, width = image.shape[:2]
    grey = image.ndim == 2
    writer = png.Writer(width, height, greyscale=grey, bitdepth=16, compression=3)
    with open(path, "wb") as handle:
        writer.write(handle, image.reshape(height, -1))


def read_png16(path: Path) -> np.ndarray:
    """Read a 16-bit PNG written by ``write_png16`` back to (H, W) or (H, W, 3) uint16."""
    width, height, rows, info = png.Reader(filename=str(path)).asDirect()
    data = np.vstack([np.asarray(row, dtype=np.uint16) for row in rows])
    planes = info["planes"]
    return data.reshape(height, width, planes) if planes > 1 else data.reshape(height, width)


def write_png8(path: Path, image: np.ndarray) -> None:
    """Write a uint8 (H, W) or (H, W, 3) image as an 8-bit PNG."""
    Image.fromarray(np.ascontiguousarray(image, dtype=np.uint8)).save(path, compress_level=3)


def write_exr(path: Path, channels: dict[str, np.ndarray]) -> None:
    """Write float32 images to a ZIP-compressed scanline OpenEXR file.

    channels: name -> (H, W) or (H, W, C) array; a 3-plane array named "RGB" becomes the
    R, G, B channels, "XYZ" the X, Y, Z channels.
    """
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    data = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    with OpenEXR.File(header, data) as exr:
        exr.write(str(path))


def read_exr(path: Path) -> dict[str, np.ndarray]:
    """Read an OpenEXR file to a dict of channel (group) name -> array."""
    with OpenEXR.File(str(path)) as exr:
        return {name: channel.pixels.copy() for name, channel in exr.channels().items()}
