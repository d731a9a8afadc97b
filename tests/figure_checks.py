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


def check_plane_of_incidence_figure(path: Path, n_channels: int, n_incidences: int) -> None:
    """A ``satsight.brdf.plot.plot_plane_of_incidence`` figure: one 4.2 x 3.4 inch panel per
    channel (three to a row) at 110 dpi, and the colour of every incidence angle (viridis
    from 0 to 0.9) on its markers and curves."""
    from matplotlib import colormaps

    cols = min(n_channels, 3)
    rows = -(-n_channels // cols)
    pixels = figure_pixels(path, (round(4.2 * cols * 110), round(3.4 * rows * 110)))
    for x in np.linspace(0.0, 0.9, n_incidences):
        assert has_colour(pixels, colormaps["viridis"](x)), f"no curve of colour viridis({x})"
