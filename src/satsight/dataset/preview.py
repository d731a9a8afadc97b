"""Images for people: the 8-bit DN preview, crops and the contact sheet."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from satsight.errors import SatsightError

#: The 8-bit previews' stretches: ``asinh`` (default: faint stars and the target both show)
#: or ``gamma`` (the earlier look, byte for byte).
PreviewStretchName = Literal["asinh", "gamma"]
PREVIEW_STRETCHES: tuple[str, ...] = ("asinh", "gamma")
DEFAULT_PREVIEW_STRETCH = "asinh"

#: Softening of the asinh stretch, DN above the bias: below it the stretch is linear, above
#: it logarithmic (Lupton et al. 2004, PASP 116, 133, Eq. 2, beta = softening). 5 DN is
#: about 6 read-noise sigma of the default detector (5 e- rms at 5.83 e-/DN = 0.86 DN), so
#: the noise stays in the darkest levels (1 sigma: 4/255, 3 sigma: 13/255) while a star of
#: 300 e- peak (51 DN) shows at 76/255 and the target above half full well at 237-255.
DEFAULT_ASINH_SOFTENING_DN = 5.0

# Display stretch of the contact sheet: value = (L / L_max) ** (1 / 2.2).
PREVIEW_GAMMA = 2.2

#: The gamma stretch of the 8-bit previews, as written into labels.json.
DN_PREVIEW_STRETCH = (
    "preview = round(255 * clip((DN - bias_dn) / (full_well_dn - bias_dn), 0, 1) ** (1 / 2.2)):"
    " black at the bias, white at full well, gamma 2.2"
)
#: The asinh stretch of the 8-bit previews, as written into labels.json ({beta}: softening).
DN_PREVIEW_ASINH_STRETCH = (
    "preview = round(255 * asinh(x / {beta:g}) / asinh(X / {beta:g})) with x = clip(DN - "
    "bias_dn, 0, X), X = full_well_dn - bias_dn: black at the bias, white at full well, linear "
    "below the softening of {beta:g} DN and logarithmic above it (Lupton et al. 2004, PASP "
    "116, 133)"
)


def _check_span(bias_dn: float, full_well_dn: float) -> float:
    span = float(full_well_dn) - float(bias_dn)
    if span <= 0:
        raise SatsightError(
            f"full_well_dn ({full_well_dn}) must exceed bias_dn ({bias_dn}); check the "
            "detector's full well, gain and bias"
        )
    return span


def dn_preview_uint8(dn: np.ndarray, bias_dn: float, full_well_dn: float) -> np.ndarray:
    """The 8-bit display image of a raw DN frame, gamma stretch (``DN_PREVIEW_STRETCH``).

    dn: (H, W) uint16 raw digital numbers. bias_dn: the detector's offset (black).
    full_well_dn: the mean output at full well (white). Returns (H, W) uint8.
    """
    span = _check_span(bias_dn, full_well_dn)
    lut = np.arange(65536, dtype=np.float64)
    lut = np.clip((lut - float(bias_dn)) / span, 0.0, 1.0) ** (1.0 / PREVIEW_GAMMA)
    lut = np.rint(255.0 * lut).astype(np.uint8)
    return lut[np.asarray(dn, dtype=np.uint16)]


def dn_preview_asinh_uint8(
    dn: np.ndarray,
    bias_dn: float,
    full_well_dn: float,
    softening_dn: float = DEFAULT_ASINH_SOFTENING_DN,
) -> np.ndarray:
    """The 8-bit display image of a raw DN frame, asinh stretch (``DN_PREVIEW_ASINH_STRETCH``).

    dn: (H, W) uint16 raw digital numbers. bias_dn: black. full_well_dn: white.
    softening_dn: beta, DN above the bias where the stretch turns from linear to
    logarithmic (Lupton et al. 2004, PASP 116, 133). Returns (H, W) uint8. Faint stars a few
    hundred electrons above the bias and the target near full well both show.
    """
    span = _check_span(bias_dn, full_well_dn)
    beta = float(softening_dn)
    if not (beta > 0 and np.isfinite(beta)):
        raise SatsightError(f"the asinh softening must be a positive number of DN, got {beta}")
    lut = np.clip(np.arange(65536, dtype=np.float64) - float(bias_dn), 0.0, span)
    lut = np.arcsinh(lut / beta) / np.arcsinh(span / beta)
    lut = np.rint(255.0 * lut).astype(np.uint8)
    return lut[np.asarray(dn, dtype=np.uint16)]


@dataclass(frozen=True)
class PreviewStretch:
    """How raw DN become the 8-bit previews: black at the bias, white at full well.

    name: ``"asinh"`` (``dn_preview_asinh_uint8``) or ``"gamma"`` (``dn_preview_uint8``).
    softening_dn: the asinh softening beta (DN above the bias); unused by gamma.
    """

    name: PreviewStretchName = DEFAULT_PREVIEW_STRETCH
    softening_dn: float = DEFAULT_ASINH_SOFTENING_DN

    def __post_init__(self) -> None:
        if self.name not in PREVIEW_STRETCHES:
            raise SatsightError(
                f"unknown preview stretch {self.name!r}; choose one of "
                f"{', '.join(PREVIEW_STRETCHES)}"
            )

    def apply(self, dn: np.ndarray, bias_dn: float, full_well_dn: float) -> np.ndarray:
        """(H, W) uint8 display image of the (H, W) uint16 raw DN ``dn``."""
        if self.name == "gamma":
            return dn_preview_uint8(dn, bias_dn, full_well_dn)
        return dn_preview_asinh_uint8(dn, bias_dn, full_well_dn, self.softening_dn)

    def header(self) -> dict:
        """The stretch as labels.json's ``preview`` entry: name, formula, parameters."""
        if self.name == "gamma":
            return {"stretch": "gamma", "formula": DN_PREVIEW_STRETCH, "gamma": PREVIEW_GAMMA}
        return {
            "stretch": "asinh",
            "formula": DN_PREVIEW_ASINH_STRETCH.format(beta=self.softening_dn),
            "softening_dn": self.softening_dn,
        }

    @classmethod
    def from_header(cls, entry: object) -> PreviewStretch:
        """The stretch a dataset's ``preview`` entry names; gamma for datasets written before
        the choice existed (their entry holds only the gamma formula)."""
        if isinstance(entry, dict) and entry.get("stretch") == "asinh":
            softening = entry.get("softening_dn", DEFAULT_ASINH_SOFTENING_DN)
            return cls("asinh", float(softening))
        return cls("gamma")


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


#: The contact sheet's cell, px: 4.2 x 4.8 inches at 100 dpi, a caption above each image.
CONTACT_CELL_PX = (420, 480)
_CAPTION_FONT_PX = 13
_HEADING_FONT_PX = 17
_MARGIN_PX = 8


def write_contact_sheet(
    path: Path, thumbnails: list[np.ndarray], titles: list[str], heading: str
) -> None:
    """A grid of frame thumbnails with one caption each, saved as PNG.

    Three cells to a row (six beyond nine frames) of `CONTACT_CELL_PX`; a two-line heading on
    top. Each thumbnail, values in [0, 1], is shown in grey (round(255 v)), enlarged by the
    largest whole factor that fits its cell (nearest neighbour, so every thumbnail pixel is
    a square of equal pixels), or shrunk to fit. Drawn with Pillow alone.
    """
    from PIL import Image, ImageDraw, ImageFont

    count = len(thumbnails)
    cols = min(count, 3 if count <= 9 else 6)
    rows = int(np.ceil(count / cols))
    cell_w, cell_h = CONTACT_CELL_PX
    caption_font = ImageFont.load_default(size=_CAPTION_FONT_PX)
    heading_font = ImageFont.load_default(size=_HEADING_FONT_PX)
    heading_text = (
        heading + "\n(crops around the target, DN above the bias; each scaled to its own "
        f"maximum, display gamma {PREVIEW_GAMMA})"
    )
    sheet = Image.new("L", (cols * cell_w, rows * cell_h), 255)
    draw = ImageDraw.Draw(sheet)
    box = draw.multiline_textbbox((0, 0), heading_text, font=heading_font, spacing=4)
    heading_h = box[3] - box[1] + 2 * _MARGIN_PX
    draw.multiline_text(
        (sheet.width // 2, _MARGIN_PX), heading_text, fill=0, font=heading_font,
        anchor="ma", align="center", spacing=4,
    )  # fmt: skip
    row_h = (sheet.height - heading_h) // rows
    for index, (image, title) in enumerate(zip(thumbnails, titles, strict=False)):
        row, col = divmod(index, cols)
        left, top = col * cell_w, heading_h + row * row_h
        draw.multiline_text(
            (left + cell_w // 2, top + _MARGIN_PX // 2), title, fill=0, font=caption_font,
            anchor="ma", align="center", spacing=2,
        )  # fmt: skip
        caption = draw.multiline_textbbox((0, 0), title, font=caption_font, spacing=2)
        image_top = top + _MARGIN_PX + caption[3] - caption[1] + _MARGIN_PX // 2
        room_w = cell_w - 2 * _MARGIN_PX
        room_h = top + row_h - _MARGIN_PX - image_top
        grey = np.round(255.0 * np.clip(np.asarray(image, dtype=np.float64), 0.0, 1.0))
        thumb = Image.fromarray(grey.astype(np.uint8))
        scale = min(room_w / thumb.width, room_h / thumb.height)
        if scale >= 1.0:
            scale = float(int(scale))
        size = (max(1, int(thumb.width * scale)), max(1, int(thumb.height * scale)))
        thumb = thumb.resize(
            size, Image.Resampling.NEAREST if scale >= 1.0 else Image.Resampling.BOX
        )
        sheet.paste(thumb, (left + (cell_w - size[0]) // 2, image_top + (room_h - size[1]) // 2))
    sheet.save(path, optimize=False)
