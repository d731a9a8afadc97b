"""What a render produces for one frame: radiance and the geometric label images."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property, lru_cache

import numpy as np


@lru_cache(maxsize=8)
def margin_pixels_xy(width: int, height: int, margin_px: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (x, y), int32, of the ring ``margin_px`` wide around a width x
    height frame, in row-major order of the padded frame: x in [-m, width + m), y in
    [-m, height + m), outside the frame. Read-only arrays (cached)."""
    m = int(margin_px)
    outside = np.ones((height + 2 * m, width + 2 * m), dtype=bool)
    outside[m : m + height, m : m + width] = False
    y, x = np.nonzero(outside)
    x = (x - m).astype(np.int32)
    y = (y - m).astype(np.int32)
    x.setflags(write=False)
    y.setflags(write=False)
    return x, y


@dataclass(frozen=True)
class RadianceImage:
    """One rendered frame, (H, W) images with pixel (0, 0) the top-left pixel centre.

    radiance_w_m2_sr: (H, W, 3) float32 radiance towards the camera per colour channel
    (None once dropped from a frame whose files do not hold it, ``FrameArrays.for_files``).
    depth_m: (H, W) float32 distance along the optical axis (+z), 0 where no surface.
    part_id: (H, W) uint16 part index + 1 of the visible surface, 0 for background.
    normals_cam: (H, W, 3) float32 unit surface normals in the camera frame, facing the
    camera; zero for background. float16 when the render was asked for half floats (a
    dataset run that writes them to a half-float file), None when asked for none.
    margin_px, margin_radiance_w_m2_sr: the radiance (n, 3) of the pixels of a ring
    ``margin_px`` wide around the frame, in ``margin_pixels_xy`` order (None without one).
    background_id: (H, W) uint8 body seen behind the target (see ``background_mask``),
    None when no body is in view. footprint: the label of the fine grid whose integral
    replaced the pixels of a small target (``satsight.render.footprint``), None without.
    target_part_count: the parts 1..P of ``part_id`` that are the target when the rendered
    mesh also holds other objects (their parts numbered after it); 0: every part is the
    target's.
    """

    radiance_w_m2_sr: np.ndarray | None
    depth_m: np.ndarray
    part_id: np.ndarray
    normals_cam: np.ndarray | None
    margin_px: int = 0
    margin_radiance_w_m2_sr: np.ndarray | None = None
    background_id: np.ndarray | None = None
    footprint: dict | None = None
    target_part_count: int = 0

    def background_mask(self) -> np.ndarray:
        """(H, W) uint8: what a pixel-centre ray that misses the target meets: 0 space,
        1 the Earth, 2 the Moon; 0 where the target is (zeros when no body is in view)."""
        if self.background_id is None:
            return np.zeros(self.shape, dtype=np.uint8)
        return self.background_id

    def padded_radiance_w_m2_sr(self) -> np.ndarray:
        """(H + 2m, W + 2m, 3) float32 radiance of the frame with its margin ring (a copy;
        the frame itself when there is no margin)."""
        m = self.margin_px
        if m == 0 or self.margin_radiance_w_m2_sr is None:
            return self.radiance_w_m2_sr
        h, w = self.shape
        padded = np.zeros((h + 2 * m, w + 2 * m, 3), dtype=np.float32)
        padded[m : m + h, m : m + w] = self.radiance_w_m2_sr
        x, y = margin_pixels_xy(w, h, m)
        padded[y + m, x + m] = self.margin_radiance_w_m2_sr
        return padded

    @cached_property
    def object_mask(self) -> np.ndarray:
        """(H, W) bool, read-only: True where a ray from the pixel centre hits the target
        (not another object of the scene). Made once per image (a frame's stages read it
        several times: 7 ms each at 4096 x 4112)."""
        if self.target_part_count > 0:
            mask = (self.part_id > 0) & (self.part_id <= self.target_part_count)
        else:
            mask = self.part_id > 0
        mask.flags.writeable = False
        return mask

    def without_radiance(self) -> RadianceImage:
        """This image without its radiance and ring, its object mask kept when made (the same
        part ids give the same mask: 7 ms less to make again at 4096 x 4112)."""
        image = replace(self, radiance_w_m2_sr=None, margin_radiance_w_m2_sr=None)
        if "object_mask" in self.__dict__:  # functools.cached_property's store
            image.__dict__["object_mask"] = self.__dict__["object_mask"]
        return image

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth_m.shape


def mask_box(mask: np.ndarray) -> tuple[slice, slice] | None:
    """(rows, columns) slices of the smallest box holding every True pixel of an (H, W)
    mask, or None when it has none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    columns = np.flatnonzero(mask[rows[0] : rows[-1] + 1].any(axis=0))  # the rows that hold it
    return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(columns[0]), int(columns[-1]) + 1)


def within_box(mask: np.ndarray) -> tuple[tuple[slice, slice], np.ndarray]:
    """(``mask_box``'s slices, empty for an empty mask; the mask within them): an image cut
    to them and indexed by that mask gives the same pixels, in the same order, as the
    whole image indexed by ``mask``, without a pass over the whole image."""
    box = mask_box(mask) or (slice(0, 0), slice(0, 0))
    return box, mask[box]
