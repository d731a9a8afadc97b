"""Images for people: max-scaled 16-bit radiance, masks and the contact sheet."""

from __future__ import annotations

from pathlib import Path

import numpy as np

# Display stretch of the contact sheet: value = (L / L_max) ** (1 / 2.2).
PREVIEW_GAMMA = 2.2


def radiance_to_uint16(radiance_w_m2_sr: np.ndarray) -> tuple[np.ndarray, float]:
    """Scale radiance linearly so the frame's maximum maps to 65535.

    Returns the uint16 image and the scale in W m^-2 sr^-1 per count (0 for a black frame).
    """
    peak = float(np.max(radiance_w_m2_sr)) if radiance_w_m2_sr.size else 0.0
    if peak <= 0.0:
        return np.zeros(radiance_w_m2_sr.shape, dtype=np.uint16), 0.0
    scaled = np.rint(np.clip(radiance_w_m2_sr / peak, 0.0, 1.0) * 65535.0)
    return scaled.astype(np.uint16), peak / 65535.0


def crop_box_xyxy_px(
    bbox_xyxy_px: list[int] | None,
    shape: tuple[int, int],
    margin: float = 0.4,
    min_side_px: int = 64,
) -> tuple[int, int, int, int]:
    """A square window around a box, grown by ``margin`` of its size and clipped to the image.

    Returns (x0, y0, x1, y1) with exclusive ends; the whole image when there is no box.
    """
    height, width = shape
    if bbox_xyxy_px is None:
        return 0, 0, width, height
    x0, y0, x1, y1 = bbox_xyxy_px
    side = max(x1 - x0 + 1, y1 - y0 + 1, min_side_px)
    side = min(int(np.ceil(side * (1.0 + 2.0 * margin))), width, height)
    cx, cy = (x0 + x1 + 1) // 2, (y0 + y1 + 1) // 2
    left = int(np.clip(cx - side // 2, 0, width - side))
    top = int(np.clip(cy - side // 2, 0, height - side))
    return left, top, left + side, top + side


def thumbnail(radiance_w_m2_sr: np.ndarray, max_side_px: int = 512) -> np.ndarray:
    """Box-averaged, gamma-stretched float image in [0, 1] no larger than max_side_px."""
    height, width = radiance_w_m2_sr.shape[:2]
    step = max(1, int(np.ceil(max(height, width) / max_side_px)))
    h, w = (height // step) * step, (width // step) * step
    small = radiance_w_m2_sr[:h, :w].reshape(h // step, step, w // step, step, -1).mean((1, 3))
    peak = small.max()
    if peak > 0:
        small = (small / peak) ** (1.0 / PREVIEW_GAMMA)
    return np.clip(small, 0.0, 1.0)


def write_contact_sheet(
    path: Path, thumbnails: list[np.ndarray], titles: list[str], heading: str
) -> None:
    """A grid of frame thumbnails with one caption each, saved as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    count = len(thumbnails)
    cols = min(count, 3)
    rows = int(np.ceil(count / cols))
    fig, axes = plt.subplots(
        rows, cols, figsize=(4.2 * cols, 4.8 * rows), squeeze=False, layout="constrained"
    )
    for ax in axes.ravel():
        ax.axis("off")
    for ax, image, title in zip(axes.ravel(), thumbnails, titles, strict=False):
        ax.imshow(image, interpolation="nearest")
        ax.set_title(title, fontsize=9)
    fig.suptitle(
        heading + "\n(crops around the target; each scaled to its own maximum, "
        f"display gamma {PREVIEW_GAMMA})"
    )
    fig.savefig(path, dpi=100, facecolor="white")
    plt.close(fig)
