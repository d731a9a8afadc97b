"""Photometric labels of a frame: the target's in-band irradiance at the camera (paper
Eq. 15) and its apparent V-equivalent magnitude.

**Irradiance.** The paper's Eq. 15 gives the irradiance the detection system receives from
the target in sunlight,

    E_target = Phi_d / S_0 = (E_sun / R_1^2) * integral over A of f_r cos(theta_i) cos(theta_r) dA.

Read physically: f_r is the BRDF (sr^-1), the integral runs over the surface the camera
sees, lit by the Sun, and R_1 is each element's own distance (it belongs inside the
integral). Then E_sun f_r cos(theta_i) is the element's radiance L towards the camera and
cos(theta_r) dA / R_1^2 the solid angle it subtends at the camera, so

    E_target = integral of L dOmega over the target's image = sum over pixels of L_pix Omega_pix,

which is what is computed here, from the rendered radiance (before the optics): it holds
everything the renderer adds to Eq. 15's single-bounce sunlight (earthshine, moonshine,
inter-reflections, self-shadowing). L_pix is the in-band radiance, the three rendered
channels combined with the sensor's channel weights (``SensorChain.channel_weights``: the
power of the band's three thirds in the solar spectrum), W m^-2 sr^-1; Omega_pix is the
pixel's solid angle through the pinhole, (p / f)^2 cos^3(theta) at its centre, within
(p / f)^2 / 4 (relative) of the exact solid angle of its footprint
(``pixel_solid_angles_sr``).

**Which pixels** (``target_footprint``). No target light lies outside the pixels whose
footprint meets the rectangle around the projected corners of the target's bounding box
(supersampled rays start inside their own pixel). Without a body drawn in the frame (the
renderer's ``background_id`` is None), the sum runs over that whole rectangle: it holds all
the target's light, including the partial light of edge pixels whose centre misses the
target and of parts thinner than a pixel that no pixel centre meets. (Procedural
satellites 7-8 m across at 300 km with f = 3 m and 15 um pixels cover 0-4 pixel centres;
the object mask grown by one pixel missed 4-74 % of their light, all of it when no centre
met the target. At 3-30 km, 0.4-20 % of the light is in edge pixels whose centre misses
the target.) With the Earth's or the Moon's disc drawn, the rectangle's pixels within one
pixel of a pixel centre that sees the body may hold its light, and are left out, unless
they lie within one pixel of the object mask (the target's pixels and the ring of edge
pixels around them, which hold the rest of a resolved target's light). Where the target
stands against the body, its ring pixels thus also hold the body's light over the part of
their footprint the target leaves free, and parts of it thinner than a pixel beyond the
ring are missed: an exact label there needs the renderer to keep the target's radiance
apart. Where it stands against black space, the label stays exact. Only the frame's pixels
count: for a target cut by the image border (``truncated``) the label is the irradiance of
its part in view.

**Magnitude.** m = m_sun - 2.5 log10(E_target / E_sun), with E_sun the Sun's in-band
irradiance at the observer (over the same band and from the same spectrum the frame was lit
with, before any Earth shadow) and m_sun = -26.76 + 5 log10(d_sun / 1 AU) the Sun's apparent
V magnitude at the observer's distance d_sun from it (Willmer 2018, ApJS 236, 47:
M_V = 4.81, so m_V = -26.76 at 1 AU, Vega system). This is a *V-equivalent* magnitude: the
V magnitude the target would have if its reflected light had the Sun's colour (grey
materials), measured through the camera's band; it is on the same scale as the catalogue
stars' V in the images (their flux comes from Bessell, Castelli & Plez's V zero point, which
puts the shipped E-490 Sun at V = -26.77 to -26.79, see the tests).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.constants import AU_M
from satsight.errors import SatsightError
from satsight.render.buffers import RadianceImage

#: Apparent V magnitude of the Sun at 1 AU, Vega system (Willmer 2018, ApJS 236, 47: absolute
#: magnitude M_V = 4.81, and -26.76 = 4.81 + 5 log10(1 AU / 10 pc), as it tabulates).
SUN_V_MAGNITUDE_AT_1_AU = -26.76

#: Rows of pixels whose solid angles are computed at once (bounds the memory of a target
#: that fills a 4096 x 4112 frame to a few tens of MB).
_ROWS_PER_CHUNK = 512


def _cos3_rows(camera: PinholeCamera, box_xyxy_px: tuple[int, int, int, int]) -> np.ndarray:
    """cos^3(theta) at the pixel centres of a window, (y1 - y0, x1 - x0) float64."""
    x0, y0, x1, y1 = (int(v) for v in box_xyxy_px)
    if x1 < x0 or y1 < y0:
        raise SatsightError(f"pixel window {box_xyxy_px} must have x1 >= x0 and y1 >= y0")
    scale = 1.0 / camera.focal_length_px
    tan_x2 = ((np.arange(x0, x1, dtype=np.float64) - camera.cx_px) * scale) ** 2
    tan_y2 = ((np.arange(y0, y1, dtype=np.float64) - camera.cy_px) * scale) ** 2
    sec2 = 1.0 + tan_x2[None, :] + tan_y2[:, None]
    return 1.0 / (sec2 * np.sqrt(sec2))


def pixel_solid_angles_sr(
    camera: PinholeCamera, box_xyxy_px: tuple[int, int, int, int]
) -> np.ndarray:
    """Solid angles (sr) of the pixels of a window, seen from the pinhole.

    box_xyxy_px: (x0, y0, x1, y1), exclusive ends, pixel indices (pixel (0, 0) is the
    top-left one, centred on (0, 0)). Returns (y1 - y0, x1 - x0) float64.

    Omega = (p / f)^2 cos^3(theta), theta the angle of the pixel centre from the optical
    axis: the midpoint rule of the pixel's exact solid angle, the integral of
    f dx dy / (f^2 + x^2 + y^2)^(3/2) over its footprint on the focal plane. Its relative
    error is about (p / f)^2 / 4 whatever the field of view (2e-8 for 15 um pixels at
    f = 5 cm; below the 3e-9 to which float64 resolves the exact closed form,
    atan(x y / (f sqrt(f^2 + x^2 + y^2))) at the four corners, for the paper's cameras).
    """
    ratio = camera.pixel_pitch_m / camera.focal_length_m
    return ratio * ratio * _cos3_rows(camera, box_xyxy_px)


def _rectangle_px(
    corners_px: Sequence[Sequence[float] | None] | None, shape: tuple[int, int]
) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1), exclusive ends, of the pixels whose footprint meets the rectangle
    around ``corners_px``, cut to the image; the whole image when there are no corners or
    one has no projection (at or behind the camera plane: the target may be anywhere)."""
    height, width = shape
    if not corners_px or any(c is None for c in corners_px):
        return 0, 0, width, height
    uv = np.asarray(corners_px, dtype=np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(uv)):
        return 0, 0, width, height
    # The pixel holding coordinate u is floor(u + 0.5).
    lo = np.floor(np.clip(uv.min(axis=0), -1e9, 1e9) + 0.5)
    hi = np.floor(np.clip(uv.max(axis=0), -1e9, 1e9) + 0.5) + 1
    x0, x1 = int(np.clip(lo[0], 0, width)), int(np.clip(hi[0], 0, width))
    y0, y1 = int(np.clip(lo[1], 0, height)), int(np.clip(hi[1], 0, height))
    return x0, y0, x1, y1


def _dilate(mask: np.ndarray) -> np.ndarray:
    """``mask`` grown by one pixel (3 x 3 neighbourhood), same shape."""
    h, w = mask.shape
    padded = np.pad(mask, 1)
    grown = np.zeros_like(mask)
    for dy in range(3):
        for dx in range(3):
            grown |= padded[dy : dy + h, dx : dx + w]
    return grown


def target_footprint(
    object_mask: np.ndarray,
    corners_px: Sequence[Sequence[float] | None] | None = None,
    background_id: np.ndarray | None = None,
) -> tuple[tuple[int, int, int, int], np.ndarray] | None:
    """The pixels whose radiance is summed as the target's (see the module docstring).

    object_mask: (H, W) bool, True where the pixel centre's ray meets the target.
    corners_px: the projected corners [u, v] of the target's bounding box (None entries for
    corners at or behind the camera plane), or None (the target may be anywhere).
    background_id: (H, W) body seen by the pixel centres that miss the target (0 space,
    > 0 the Earth or the Moon), or None when no body is drawn.
    Returns (box, region): box (x0, y0, x1, y1) with exclusive ends, the pixels whose
    footprint meets the rectangle around the corners, and region its (h, w) bool pixels:
    all of them without a body; with one, all but those within one pixel of a pixel centre
    that sees the body, unless within one pixel of the object mask. None when no pixel is
    summed.
    """
    mask = np.asarray(object_mask, dtype=bool)
    height, width = mask.shape
    x0, y0, x1, y1 = _rectangle_px(corners_px, mask.shape)
    if x0 >= x1 or y0 >= y1:
        return None  # the target's box lies outside the frame
    if background_id is None:
        return (x0, y0, x1, y1), np.ones((y1 - y0, x1 - x0), dtype=bool)
    # One pixel more on each side, so that the dilations see their neighbours.
    gx0, gy0 = max(x0 - 1, 0), max(y0 - 1, 0)
    gx1, gy1 = min(x1 + 1, width), min(y1 + 1, height)
    body = np.asarray(background_id)[gy0:gy1, gx0:gx1] > 0
    region = _dilate(mask[gy0:gy1, gx0:gx1]) | ~_dilate(body)
    region = region[y0 - gy0 : y1 - gy0, x0 - gx0 : x1 - gx0]
    if not region.any():
        return None
    return (x0, y0, x1, y1), region


def target_irradiance_w_m2(
    radiance_w_m2_sr: np.ndarray,
    channel_weights: np.ndarray,
    camera: PinholeCamera,
    footprint: tuple[tuple[int, int, int, int], np.ndarray] | None,
) -> float:
    """In-band irradiance at the camera from the target (W m^-2, paper Eq. 15).

    radiance_w_m2_sr: (H, W, 3) rendered radiance towards the camera per channel.
    channel_weights: (3,) weights that combine the channels into the in-band radiance
    (``SensorChain.channel_weights``, R, G, B). camera: the pinhole the frame was rendered
    with. footprint: ``target_footprint``'s (box, region), or None (no target pixel: 0).
    Returns sum over the region of L_band * Omega_pixel.
    """
    radiance = np.asarray(radiance_w_m2_sr)
    if radiance.ndim != 3 or radiance.shape[2] != 3:
        raise SatsightError(f"radiance must be (H, W, 3) W m^-2 sr^-1, got shape {radiance.shape}")
    if radiance.shape[:2] != (camera.height_px, camera.width_px):
        raise SatsightError(
            f"radiance of {radiance.shape[1]} x {radiance.shape[0]} px does not match the "
            f"camera's {camera.width_px} x {camera.height_px} px"
        )
    if footprint is None:
        return 0.0
    (x0, y0, x1, y1), region = footprint
    weights = np.asarray(channel_weights, dtype=np.float32).reshape(3)
    whole = bool(region.all())
    total = 0.0
    for top in range(y0, y1, _ROWS_PER_CHUNK):
        bottom = min(top + _ROWS_PER_CHUNK, y1)
        band = radiance[top:bottom, x0:x1].astype(np.float32, copy=False) @ weights
        if not whole:
            band *= region[top - y0 : bottom - y0]
        cos3 = _cos3_rows(camera, (x0, top, x1, bottom)).astype(np.float32)
        total += float(np.einsum("ij,ij->", band, cos3, dtype=np.float64))
    ratio = camera.pixel_pitch_m / camera.focal_length_m
    return total * ratio * ratio


def sun_v_magnitude(sun_distance_m: float) -> float:
    """The Sun's apparent V magnitude at ``sun_distance_m`` from it:
    -26.76 + 5 log10(d / 1 AU) (Willmer 2018)."""
    d = float(sun_distance_m)
    if not (d > 0 and math.isfinite(d)):
        raise SatsightError(f"the Sun's distance must be a positive number of m, got {d}")
    return SUN_V_MAGNITUDE_AT_1_AU + 5.0 * math.log10(d / AU_M)


def v_magnitude_equivalent(
    target_irradiance_w_m2: float, sun_irradiance_w_m2: float, sun_distance_m: float
) -> float | None:
    """Apparent V-equivalent magnitude of the target (see the module docstring).

    target_irradiance_w_m2: the target's in-band irradiance at the camera. sun_irradiance_w_m2:
    the Sun's in-band irradiance at the camera over the same band (unshadowed).
    sun_distance_m: the camera's distance from the Sun. Returns
    m_sun(d) - 2.5 log10(E_target / E_sun), or None when the target sends no light.
    """
    e_sun = float(sun_irradiance_w_m2)
    if not (e_sun > 0 and math.isfinite(e_sun)):
        raise SatsightError(f"the Sun's irradiance must be positive W m^-2, got {e_sun}")
    e_target = float(target_irradiance_w_m2)
    if not e_target > 0:
        return None
    return sun_v_magnitude(sun_distance_m) - 2.5 * math.log10(e_target / e_sun)


def frame_photometry(
    image: RadianceImage,
    camera: PinholeCamera,
    channel_weights: np.ndarray,
    corners_px: Sequence[Sequence[float] | None] | None,
    sun_irradiance_w_m2: float,
    sun_distance_m: float,
) -> dict:
    """A frame's photometric labels, JSON-ready.

    image: the rendered frame. camera: its pinhole. channel_weights: (3,) in-band channel
    weights. corners_px: projected corners of the target's bounding box (or None).
    sun_irradiance_w_m2, sun_distance_m: the Sun's unshadowed in-band irradiance at the
    camera and the camera's distance from the Sun.
    Keys: ``target_irradiance_w_m2`` (float, W m^-2) and ``target_v_magnitude_equivalent``
    (float, or None when the target sends no light).
    """
    footprint = target_footprint(image.object_mask, corners_px, image.background_id)
    irradiance = target_irradiance_w_m2(image.radiance_w_m2_sr, channel_weights, camera, footprint)
    return {
        "target_irradiance_w_m2": irradiance,
        "target_v_magnitude_equivalent": v_magnitude_equivalent(
            irradiance, sun_irradiance_w_m2, sun_distance_m
        ),
    }
