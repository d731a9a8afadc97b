"""The target's footprint integrated over area: small and sub-pixel targets keep their flux.

A pixel-centre sample (or s x s of them) counts a target smaller than a pixel as all or
nothing, and one a few pixels wide with edge errors of order 1 / (width x s): a sub-pixel
satellite vanishes or fills a whole pixel. A frame whose target is small on the image is
therefore rendered twice: the frame as usual, then the target's projected box on a fine
grid whose cells are summed into the pixels they fall in, which replaces those pixels.

The box is the projection of the 8 corners of the target's bounding box (it holds the
target's whole image: all corners in front of the camera, the projection of the box's
convex hull lies in the convex hull of the projected corners). The grid's square cells,
1/m px wide and aligned with the pixels so that each lies in one pixel, put at least
``FOOTPRINT_SAMPLES_ACROSS`` across the box's shorter side (so the area of a target of any
size is integrated with an edge error of about 0.6 / FOOTPRINT_SAMPLES_ACROSS of it,
0.45 %), at most ``FOOTPRINT_MAX_SAMPLES`` in all. It is used when it puts more paths in a
pixel (m^2) than the frame's own passes (supersampling^2 x samples per pixel).

Precision: a camera ray in float32 resolves ~6e-8 rad, 0.012 px at f = 3 m with 15 um
pixels, coarser than the grid of a target at GEO (0.05 px across). The grid's rays are
therefore made in float64 and anchored at the target: each starts on the plane through
the box centre (z_cam of the centre), at the point the exact perspective ray through its
grid position crosses it, stepped back in front of the target's bounding sphere; only its
direction is rounded to float32, which moves its hit by ~6e-8 x the target's size.

Pixel values: the mean radiance over the pixel's area, sum over its cells of L h^2 plus
the background (Earth, Moon or black space, at the pixel centre) over the pixel's area the
cells do not cover. Pixel (u, v) spans [u - 1/2, u + 1/2] x [v - 1/2, v + 1/2] (pixel
centres at integers, as everywhere in the renderer), and holds m x m cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import RigidTransform

#: Grid cells across the shorter side of the target's projected box.
FOOTPRINT_SAMPLES_ACROSS = 128
#: The most grid cells in one frame (a long, thin target gets a coarser grid).
FOOTPRINT_MAX_SAMPLES = 1 << 21
#: The footprint grid is made only for a target at least this many bounding radii away
#: (nearer, the target is large on any image).
_MIN_DISTANCE_RADII = 4.0


@dataclass(frozen=True)
class FootprintGrid:
    """The fine grid over a small target's projected box, and where its cells go.

    box_xyxy_px: the target's projected box (x0, y0, x1, y1), px, before clipping to the
    frame. spacing_px: (hx, hy), the cell size, px. x_px, y_px: (n,) float64 image
    positions of the cell centres, in the frame. pixel_index: (n,) int64 flat index
    (row-major) of the pixel each cell falls in. pixels: the distinct flat indices, sorted.
    origin_render_m: (n, 3) float64 ray starts (render space: body frame about the mesh
    centre), in front of the target. direction_body: (n, 3) float64 unit ray directions.
    """

    box_xyxy_px: tuple[float, float, float, float]
    spacing_px: tuple[float, float]
    x_px: np.ndarray
    y_px: np.ndarray
    pixel_index: np.ndarray
    pixels: np.ndarray
    origin_render_m: np.ndarray
    direction_body: np.ndarray
    frame_width_px: int

    @property
    def sample_count(self) -> int:
        return int(self.x_px.size)

    @property
    def sub_pixel(self) -> bool:
        """Whether the projected box is smaller than a pixel both ways."""
        x0, y0, x1, y1 = self.box_xyxy_px
        return x1 - x0 < 1.0 and y1 - y0 < 1.0

    def label(self) -> dict:
        """The frame label of the footprint (JSON-ready)."""
        return {
            "integrated": True,
            "projected_box_xyxy_px": [float(v) for v in self.box_xyxy_px],
            "sub_pixel": self.sub_pixel,
            "sample_spacing_px": [float(v) for v in self.spacing_px],
            "sample_count": self.sample_count,
        }


def projected_box_px(
    camera: PinholeCamera, cam_from_body: RigidTransform, box_corners_body_m: np.ndarray
) -> tuple[float, float, float, float] | None:
    """(x0, y0, x1, y1), px, of the projected corners of the target's box; None when a
    corner is at or behind the camera plane."""
    corners_cam = cam_from_body.apply(np.asarray(box_corners_body_m, dtype=np.float64))
    if np.any(corners_cam[:, 2] <= 0.0):
        return None
    x = camera.focal_length_px * corners_cam[:, 0] / corners_cam[:, 2] + camera.cx_px
    y = camera.focal_length_px * corners_cam[:, 1] / corners_cam[:, 2] + camera.cy_px
    return float(x.min()), float(y.min()), float(x.max()), float(y.max())


def plan_footprint(
    camera: PinholeCamera,
    cam_from_body: RigidTransform,
    box_corners_body_m: np.ndarray,
    center_body_m: np.ndarray,
    bounding_radius_m: float,
    passes_per_pixel: int,
) -> FootprintGrid | None:
    """The footprint grid of a frame, or None when it would not put more paths in a pixel
    than the frame's own ``passes_per_pixel``, the target is near, or its box misses the
    frame.

    Cells are squares of side 1/m px aligned with the pixels (each lies in one pixel), m
    the smallest integer that puts ``FOOTPRINT_SAMPLES_ACROSS`` cells across the box's
    shorter side (fewer when the cells would pass ``FOOTPRINT_MAX_SAMPLES``); they cover
    the box, clipped to the frame, rounded out to whole cells.
    """
    box = projected_box_px(camera, cam_from_body, box_corners_body_m)
    if box is None:
        return None
    center_cam = cam_from_body.apply(np.asarray(center_body_m, dtype=np.float64))
    if center_cam[2] < _MIN_DISTANCE_RADII * bounding_radius_m:
        return None
    x0, y0, x1, y1 = box
    # Clip to the frame's area; nothing to do when the box misses it.
    cx0, cy0 = max(x0, -0.5), max(y0, -0.5)
    cx1, cy1 = min(x1, camera.width_px - 0.5), min(y1, camera.height_px - 0.5)
    if cx1 <= cx0 or cy1 <= cy0:
        return None
    shorter = max(min(x1 - x0, y1 - y0), 1e-9)
    m = math.ceil(FOOTPRINT_SAMPLES_ACROSS / shorter)
    m = max(1, min(m, math.floor(math.sqrt(FOOTPRINT_MAX_SAMPLES / ((cx1 - cx0) * (cy1 - cy0))))))
    if m * m <= passes_per_pixel:
        return None
    # Cell k spans [k/m - 1/2, (k+1)/m - 1/2): cell columns kx0 <= k < kx1 cover [cx0, cx1].
    kx0, kx1 = math.floor((cx0 + 0.5) * m), math.ceil((cx1 + 0.5) * m)
    ky0, ky1 = math.floor((cy0 + 0.5) * m), math.ceil((cy1 + 0.5) * m)
    kx = np.arange(kx0, kx1)
    ky = np.arange(ky0, ky1)
    cols = np.tile(kx, ky.size)
    rows = np.repeat(ky, kx.size)
    x_px = (cols + 0.5) / m - 0.5
    y_px = (rows + 0.5) / m - 0.5
    pixel_index = (rows // m) * camera.width_px + cols // m
    origin, direction = _anchored_rays(
        camera, cam_from_body, x_px, y_px, center_cam, bounding_radius_m
    )
    return FootprintGrid(
        box_xyxy_px=box,
        spacing_px=(1.0 / m, 1.0 / m),
        x_px=x_px,
        y_px=y_px,
        pixel_index=pixel_index,
        pixels=np.unique(pixel_index),
        origin_render_m=origin,
        direction_body=direction,
        frame_width_px=camera.width_px,
    )


def _anchored_rays(
    camera: PinholeCamera,
    cam_from_body: RigidTransform,
    x_px: np.ndarray,
    y_px: np.ndarray,
    center_cam: np.ndarray,
    bounding_radius_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Ray starts (render space) and unit directions (body frame), float64, of the
    perspective rays through image positions (x_px, y_px): each anchored where it crosses
    the plane z_cam = z of the box centre, then moved back in front of the bounding sphere
    (render space is the body frame about the box centre, the mesh centre)."""
    z, f = center_cam[2], camera.focal_length_px
    on_plane_cam = np.stack(
        [(x_px - camera.cx_px) / f * z, (y_px - camera.cy_px) / f * z, np.full_like(x_px, z)],
        axis=-1,
    )
    direction_cam = on_plane_cam / np.linalg.norm(on_plane_cam, axis=-1, keepdims=True)
    body_from_cam = cam_from_body.inverse()
    R = body_from_cam.R_a_from_b
    # Render-space point: R (p_cam - c_cam) + (centre in render space = 0), so the large
    # camera distance cancels before any rounding to float32.
    on_plane_render = (on_plane_cam - center_cam) @ R.T
    direction_body = direction_cam @ R.T
    # Step back along the ray past the bounding sphere (about the mesh centre, the render
    # origin): the sphere's chord lies within R of the point nearest the centre.
    nearest_t = -np.sum(on_plane_render * direction_body, axis=-1)
    back_m = nearest_t - 1.001 * bounding_radius_m - 1e-3
    origin = on_plane_render + back_m[:, None] * direction_body
    return origin, direction_body


def compose_pixels(
    grid: FootprintGrid, sample_radiance: np.ndarray, background: np.ndarray | None
) -> np.ndarray:
    """(len(grid.pixels), 3) float64 mean radiance of the grid's pixels: the sum over each
    pixel's cells of L h^2, plus ``background`` (per pixel, (len(pixels), 3), or None for
    black space) over the pixel area the cells do not cover."""
    cell_area = grid.spacing_px[0] * grid.spacing_px[1]
    slot = np.searchsorted(grid.pixels, grid.pixel_index)
    samples = np.asarray(sample_radiance, dtype=np.float64)
    # Per channel, the cells' sums in their order (as np.add.at, at a tenth of its time).
    total = np.stack(
        [np.bincount(slot, samples[:, c], minlength=grid.pixels.size) for c in range(3)], axis=1
    )
    covered = np.bincount(slot, minlength=grid.pixels.size) * cell_area
    values = total * cell_area
    if background is not None:
        values += np.asarray(background, dtype=np.float64) * np.maximum(1.0 - covered, 0.0)[:, None]
    return values
