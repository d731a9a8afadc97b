"""A rendered frame's in-band irradiance before the blur, on the grid of the frame and its
margin ring, and the window of it that the auto exposure reads.

The grid is (H + 2 m, W + 2 m): the frame with the ring of ``RadianceImage.margin_px`` = m
pixels around it (m = 0 without a ring), the frame's pixel (0, 0) at grid (m, m). A window
is (row0, row1, col0, col1) on that grid, end exclusive.
"""

from __future__ import annotations

import numpy as np

from satsight.errors import SatsightError
from satsight.render.buffers import RadianceImage, margin_pixels_xy

#: Reach of the blur stage around a pixel, in kernel radii: the kernel spreads light one
#: radius; the negative-lobe filling (``satsight.sensor.convolution.fill_negative_lobes``)
#: moves a dip's deficit onto the positive pixels within one radius of the dip, each share
#: set by the positive pixels within one radius of it: two radii more.
BLUR_REACH_RADII = 3

#: A window larger than this fraction of the grid is widened to the whole grid: the frame's
#: irradiance is then made once, for the exposure and for the detector alike.
WHOLE_GRID_FRACTION = 0.5


def grid_shape(image: RadianceImage) -> tuple[int, int]:
    """(H + 2 m, W + 2 m): the grid of the frame and its ring (m = 0 without one)."""
    h, w = image.shape
    m = ring_width_px(image)
    return h + 2 * m, w + 2 * m


def ring_width_px(image: RadianceImage) -> int:
    """The ring's width m, pixels (0 when the image carries no ring radiance)."""
    return int(image.margin_px) if image.margin_radiance_w_m2_sr is not None else 0


def window_around(
    image: RadianceImage, box: tuple[slice, slice] | None, reach_px: int
) -> tuple[int, int, int, int] | None:
    """The grid window of the pixels within ``reach_px`` of the frame box ``box`` (rows,
    columns of frame pixels), cut to the grid; None (the whole grid) for no box, or when the
    window would cover more than ``WHOLE_GRID_FRACTION`` of the grid."""
    if box is None:
        return None
    m = ring_width_px(image)
    gh, gw = grid_shape(image)
    r0, r1 = max(box[0].start + m - reach_px, 0), min(box[0].stop + m + reach_px, gh)
    c0, c1 = max(box[1].start + m - reach_px, 0), min(box[1].stop + m + reach_px, gw)
    if (r1 - r0) * (c1 - c0) > WHOLE_GRID_FRACTION * gh * gw:
        return None
    return r0, r1, c0, c1


def detected_input(
    image: RadianceImage,
    weights: np.ndarray,
    window: tuple[int, int, int, int] | None = None,
) -> tuple[np.ndarray, tuple[int, int, int, int] | None]:
    """(the in-band irradiance before the blur on ``window`` of the grid (whole by default),
    float32, W m^-2; the box (row0, row1, col0, col1) of its non-zero samples in that
    array, None when all are 0).

    Each pixel's value is its radiance (frame or ring) times ``weights`` (3,) float32, the
    channel weights with the camera equation folded in. Only the bounding box of the
    non-zero radiance is multiplied (the renderer's background is 0); np.zeros maps pages
    lazily, so the empty parts of a whole grid cost nothing.
    """
    radiance = image.radiance_w_m2_sr
    h, w = radiance.shape[:2]
    m = ring_width_px(image)
    gh, gw = h + 2 * m, w + 2 * m
    g0, g1, k0, k1 = (0, gh, 0, gw) if window is None else window
    focal = np.zeros((g1 - g0, k1 - k0), dtype=np.float32)
    boxes = []
    # The frame's part of the window, in frame pixels.
    f0, f1 = max(g0 - m, 0), min(g1 - m, h)
    e0, e1 = max(k0 - m, 0), min(k1 - m, w)
    if f0 < f1 and e0 < e1:
        part = radiance if window is None else radiance[f0:f1, e0:e1]
        # Row maxima (a contiguous reduction for the whole frame), then column maxima over
        # the rows that hold light.
        rows = np.flatnonzero(part.reshape(part.shape[0], -1).max(axis=1, initial=0.0) > 0)
        if rows.size:
            band = part[rows[0] : rows[-1] + 1]
            cols = np.flatnonzero(band.max(axis=0).max(axis=1) > 0)
            r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
            # The same rows and columns on the window's array.
            a0, b0 = f0 + m - g0, e0 + m - k0
            np.matmul(
                part[r0:r1, c0:c1].astype(np.float32, copy=False),
                weights,
                out=focal[a0 + r0 : a0 + r1, b0 + c0 : b0 + c1],
            )
            boxes.append((a0 + r0, a0 + r1, b0 + c0, b0 + c1))
    if m:
        _add_ring(image, weights, focal, (g0, g1, k0, k1), boxes)
    if not boxes:
        return focal, None
    return focal, (
        min(b[0] for b in boxes),
        max(b[1] for b in boxes),
        min(b[2] for b in boxes),
        max(b[3] for b in boxes),
    )


def _add_ring(
    image: RadianceImage,
    weights: np.ndarray,
    focal: np.ndarray,
    window: tuple[int, int, int, int],
    boxes: list,
) -> None:
    """Write the ring's in-band irradiance into ``focal`` (``window`` of the grid) and add
    the box of its non-zero values to ``boxes``."""
    h, w = image.radiance_w_m2_sr.shape[:2]
    m = image.margin_px
    ring = np.asarray(image.margin_radiance_w_m2_sr, dtype=np.float32)
    x, y = margin_pixels_xy(w, h, m)
    if ring.shape != (x.size, 3):
        raise SatsightError(
            f"the margin ring of a {w} x {h} frame, {m} px wide, holds {x.size} pixels "
            f"(n, 3); got radiance of shape {ring.shape}"
        )
    g0, g1, k0, k1 = window
    if (g0, g1, k0, k1) == (0, h + 2 * m, 0, w + 2 * m):
        values = ring @ weights  # (n,), > 0 where any channel is (the weights are)
        # The ring in row-major order of the grid: m full rows on top, two m-wide strips
        # beside each frame row, m full rows below.
        top, beside = m * (w + 2 * m), 2 * m * h
        sides = values[top : top + beside].reshape(h, 2 * m)
        focal[:m] = values[:top].reshape(m, w + 2 * m)
        focal[m + h :] = values[top + beside :].reshape(m, w + 2 * m)
        focal[m : m + h, :m] = sides[:, :m]
        focal[m : m + h, m + w :] = sides[:, m:]
        gy, gx = y + m, x + m
    else:
        gy, gx = y + m, x + m
        inside = (gy >= g0) & (gy < g1) & (gx >= k0) & (gx < k1)
        values = ring[inside] @ weights
        gy, gx = gy[inside] - g0, gx[inside] - k0
        focal[gy, gx] = values
    lit = values > 0
    if lit.any():
        ys, xs = gy[lit], gx[lit]
        boxes.append((int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1))
