"""The target's silhouette beyond the image border, for BOP's ``px_count_all``/``bbox_obj``.

BOP counts the whole projected object, the part cut off by the image border included
(bop_toolkit scripts/calc_gt_info.py renders the model on a canvas three times the image
size, the image in its middle: columns [-W, 2W), rows [-H, 2H)). The dataset's object mask
holds only the pixels inside the image; the pixels outside come from here: the model's
triangles projected through K and the pose and filled at pixel centres, the same rule as
the renderer's mask (a pixel is the target's where the ray through its centre hits it).

Pixel coordinates follow satsight (pixel (0, 0) is the centre of the top-left pixel).
Triangles with a corner at or behind the camera plane are left out (a target straddling
the camera has no BOP silhouette either).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Triangles whose pixel box is at most this many pixels a side are filled in batches.
_SMALL_PX = 8
_BATCH = 65536


@dataclass(frozen=True)
class OutsideSilhouette:
    """The silhouette's pixels outside the image, within BOP's canvas.

    pixel_count: how many. bbox_xyxy_px: their box [x0, y0, x1, y1] (inclusive pixel
    indices, in the image's pixel coordinates, so negative left of and above it), or None.
    """

    pixel_count: int
    bbox_xyxy_px: list[int] | None


def _edge(a: np.ndarray, b: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Twice the signed area of (a, b, p): positive when p is left of a -> b."""
    return (b[..., 0] - a[..., 0]) * (py - a[..., 1]) - (b[..., 1] - a[..., 1]) * (px - a[..., 0])


def _inside(tri: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Whether the points (px, py) lie in the triangles (either winding, edges included).

    tri: (N, 3, 2) broadcast against px, py of shape (N, M)."""
    a, b, c = (tri[:, k, None, :] for k in range(3))
    e0, e1, e2 = _edge(a, b, px, py), _edge(b, c, px, py), _edge(c, a, px, py)
    return ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))


def fill_triangles(canvas: np.ndarray, origin_xy: tuple[int, int], tri_px: np.ndarray) -> None:
    """Set the canvas pixels whose centres lie in any of the triangles, in place.

    canvas: (h, w) bool; its pixel (0, 0) is the image pixel ``origin_xy``. tri_px:
    (N, 3, 2) corners in image pixel coordinates. Degenerate triangles fill nothing.
    """
    tri_px = np.asarray(tri_px, dtype=np.float64)
    ab, ac = tri_px[:, 1] - tri_px[:, 0], tri_px[:, 2] - tri_px[:, 0]
    area = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    tri_px = tri_px[np.isfinite(area) & (area != 0)]
    x0, y0 = origin_xy
    h, w = canvas.shape
    lo = np.ceil(tri_px.min(axis=1)).astype(np.int64)
    hi = np.floor(tri_px.max(axis=1)).astype(np.int64)
    lo = np.maximum(lo, [x0, y0])
    hi = np.minimum(hi, [x0 + w - 1, y0 + h - 1])
    keep = np.all(hi >= lo, axis=1)
    tri_px, lo, hi = tri_px[keep], lo[keep], hi[keep]
    span = hi - lo + 1
    small = np.all(span <= _SMALL_PX, axis=1)
    grid_x, grid_y = (g.ravel() for g in np.meshgrid(np.arange(_SMALL_PX), np.arange(_SMALL_PX)))
    for start in range(0, int(small.sum()), _BATCH):
        sel = np.flatnonzero(small)[start : start + _BATCH]
        px = lo[sel, 0, None] + grid_x
        py = lo[sel, 1, None] + grid_y
        hit = (grid_x < span[sel, 0, None]) & (grid_y < span[sel, 1, None])
        hit &= _inside(tri_px[sel], px.astype(np.float64), py.astype(np.float64))
        canvas[py[hit] - y0, px[hit] - x0] = True
    for k in np.flatnonzero(~small):
        xs = np.arange(lo[k, 0], hi[k, 0] + 1)
        ys = np.arange(lo[k, 1], hi[k, 1] + 1)
        px, py = np.meshgrid(xs.astype(np.float64), ys.astype(np.float64))
        hit = _inside(tri_px[k : k + 1], px.reshape(1, -1), py.reshape(1, -1))[0]
        window = canvas[ys[0] - y0 : ys[-1] - y0 + 1, xs[0] - x0 : xs[-1] - x0 + 1]
        window |= hit.reshape(window.shape)


def project_triangles(
    vertices_body_m: np.ndarray,
    faces: np.ndarray,
    R_cam_from_body: np.ndarray,
    t_cam_from_body_m: np.ndarray,
    K: np.ndarray,
) -> np.ndarray:
    """(N, 3, 2) pixel corners of the triangles wholly in front of the camera."""
    points = vertices_body_m @ np.asarray(R_cam_from_body).T + np.asarray(t_cam_from_body_m)
    z = points[:, 2]
    front = np.all(z[faces] > 0, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K[0, 0] * points[:, 0] / z + K[0, 1] * points[:, 1] / z + K[0, 2]
        v = K[1, 1] * points[:, 1] / z + K[1, 2]
    uv = np.stack([u, v], axis=-1)
    return uv[faces[front]]


def outside_silhouette(
    vertices_body_m: np.ndarray,
    faces: np.ndarray,
    R_cam_from_body: np.ndarray,
    t_cam_from_body_m: np.ndarray,
    K: np.ndarray,
    size_px: tuple[int, int],
) -> OutsideSilhouette:
    """The target's silhouette pixels outside the (W, H) image, inside BOP's canvas.

    Only triangles with a corner outside the image can cover a pixel outside it, and only
    those are filled, on a canvas just large enough for them.
    """
    width, height = size_px
    tri = project_triangles(vertices_body_m, faces, R_cam_from_body, t_cam_from_body_m, K)
    corners = tri.reshape(-1, 3, 2)
    out = (corners[..., 0] < -0.5) | (corners[..., 0] > width - 0.5)
    out |= (corners[..., 1] < -0.5) | (corners[..., 1] > height - 0.5)
    tri = tri[np.any(out, axis=1)]
    if tri.size == 0:
        return OutsideSilhouette(0, None)
    lo = np.maximum(np.floor(tri.min(axis=(0, 1))).astype(np.int64), [-width, -height])
    hi = np.minimum(np.ceil(tri.max(axis=(0, 1))).astype(np.int64), [2 * width - 1, 2 * height - 1])
    if np.any(hi < lo):
        return OutsideSilhouette(0, None)
    canvas = np.zeros((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), dtype=bool)
    fill_triangles(canvas, (int(lo[0]), int(lo[1])), tri)
    # The image itself: its pixels are the dataset mask's, not counted here.
    ix0, iy0 = max(0, -lo[0]), max(0, -lo[1])
    ix1, iy1 = min(canvas.shape[1], width - lo[0]), min(canvas.shape[0], height - lo[1])
    if ix1 > ix0 and iy1 > iy0:
        canvas[iy0:iy1, ix0:ix1] = False
    ys = np.flatnonzero(canvas.any(axis=1))
    if ys.size == 0:
        return OutsideSilhouette(0, None)
    xs = np.flatnonzero(canvas.any(axis=0))
    box = [int(xs[0] + lo[0]), int(ys[0] + lo[1]), int(xs[-1] + lo[0]), int(ys[-1] + lo[1])]
    return OutsideSilhouette(int(np.count_nonzero(canvas)), box)
