"""Checks of the content of a written figure (a matplotlib PNG), not only of its file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# A figure with axes, ticks, labels and curves has hundreds of distinct colours once
# anti-aliased; a blank or single-colour canvas has one or two.
MIN_DISTINCT_COLOURS = 10


def figure_pixels(path: Path, size_px: tuple[int, int] | None = None) -> np.ndarray:
    """The (H, W, 3) uint8 pixels of the PNG figure at ``path``, after checking that it is a
    PNG, not (nearly) blank, and, when given, that it is ``size_px`` = (width, height)."""
    path = Path(path)
    assert path.is_file(), path
    assert path.read_bytes()[:8] == PNG_SIGNATURE, path
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB"))
    if size_px is not None:
        assert (pixels.shape[1], pixels.shape[0]) == size_px, (pixels.shape, size_px)
    packed = pixels.astype(np.uint32) @ np.array([1 << 16, 1 << 8, 1], dtype=np.uint32)
    assert np.unique(packed).size > MIN_DISTINCT_COLOURS, f"{path} is (nearly) blank"
    return pixels


def has_colour(pixels: np.ndarray, rgba: tuple[float, ...], atol: int = 2) -> bool:
    """Whether some pixel has the matplotlib colour ``rgba`` (components in [0, 1]) within
    ``atol`` of 255 in every channel (markers and line centres keep their colour exactly)."""
    target = np.round(np.asarray(rgba[:3]) * 255.0)
    return bool(np.any(np.all(np.abs(pixels.astype(int) - target) <= atol, axis=-1)))
