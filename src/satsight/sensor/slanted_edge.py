"""Slanted-edge MTF of an image: the ISO 12233 edge method, for checking generated frames.

The method (ISO 12233:2017, "Photography - Electronic still picture imaging - Resolution and
spatial frequency responses", its edge-based e-SFR; Reichenbach, Park & Narayanswamy, Opt.
Eng. 30(2), 170 (1991); Burns, "Slanted-edge MTF for digital camera and scanner analysis",
Proc. IS&T PICS 2000, 135): a straight edge a few degrees from the pixel columns is located row
by row (centroid of the row's derivative) and fitted with a line; every pixel is projected
onto the edge normal, so the rows, each at another sub-pixel phase, together sample the
edge spread function (ESF) finer than the pixel pitch; the ESF is binned, differentiated
into the line spread function (LSF), Hann-windowed and Fourier transformed; its modulus,
normalised at zero frequency, is the MTF along the edge normal, beyond the pixel Nyquist
frequency.

Two ways to bin the projected pixels:

* ``oversampling=k`` (ISO: 4, the default): bins 1/k px wide. Averaging a bin blurs the
  ESF by a box of 1/k px and the centred-difference derivative filters it by sinc(2 nu / k);
  both are divided out (as ISO 12233 does for the derivative). This assumes an ESF that is
  smooth on the bin scale, as a camera's is.
* ``phases_per_px=N``: for an edge drawn with a slope of exactly 1/N (N whole), whose pixel
  centres fall on exactly N phases per pixel, every phase gets its own bin (the fitted
  slope must be within 1 % of 1/N; the pixels' row centroids of a rendered frame locate the
  edge only to ~0.2 % in slope, too coarsely to find N's lattice by themselves). A
  rendered frame made from point samples at the pixel centres and a discrete kernel has an
  ESF that is a staircase with its steps on that lattice: its LSF is a comb whose spectrum
  repeats beyond Nyquist instead of falling off, and coarser bins fold that spectrum back
  into the measurement (up to +-5 % at Nyquist with 4x bins at 5 deg, depending on the
  edge's phase). Per-phase bins read the staircase exactly: the first difference of the
  ESF is the comb, whose transform is the frame's response along the normal. For a smooth
  ESF the first difference is a box of cos(theta) / N px, a loss sinc(nu cos(theta) / N)
  that is not divided out (0.3 % at Nyquist for N = 11).

Frequencies are in cycles per pixel along the edge normal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError

#: Largest relative difference between the fitted slope and the 1/N of per-phase bins.
_LATTICE_SLOPE_TOLERANCE = 0.01


@dataclass(frozen=True)
class EdgeMtf:
    """An MTF measured on a slanted edge.

    frequency_cyc_per_px: (F,) frequencies along the edge normal, cycles per pixel, from 0.
    mtf: (F,) the MTF there, 1 at zero frequency. angle_rad: the edge's angle from the pixel
    columns (dx/dy = tan(angle)). phases_per_px: N of the per-phase bins (None with ISO
    bins). esf: the binned edge spread function (from the dark side), in the image's units.
    """

    frequency_cyc_per_px: np.ndarray
    mtf: np.ndarray
    angle_rad: float
    phases_per_px: int | None
    esf: np.ndarray


def _edge_line(image: np.ndarray, half_width_px: float) -> tuple[float, float]:
    """(x0, slope): the edge's column x = x0 + slope * row. First each row's steepest step,
    fitted by a line; then, three times, the centroid of each row's derivative (signed towards the
    edge's step) under a Hann window of +-half_width_px around the last fit, fitted by least
    squares (as ISO 12233's e-SFR does; the window keeps other structure, such as a frame border,
    out of the centroids)."""
    h, w = image.shape
    deriv = np.diff(image, axis=1)  # (h, w - 1), at x + 1/2
    deriv = deriv * math.copysign(1.0, deriv.sum())
    x = np.arange(w - 1) + 0.5
    rows = np.arange(h, dtype=np.float64)
    slope, x0 = np.polyfit(rows, x[np.argmax(deriv, axis=1)], 1)
    for _ in range(3):
        offset = x[None, :] - (x0 + slope * rows[:, None])
        window = np.where(
            np.abs(offset) < half_width_px,
            0.5 + 0.5 * np.cos(math.pi * offset / half_width_px),
            0.0,
        )
        d = deriv * window
        total = d.sum(axis=1)
        if np.any(total <= 0):
            raise SatsightError(
                "every row must cross the edge (a step in its values); some rows do not. "
                "Crop the image to rows that hold the edge."
            )
        slope, x0 = np.polyfit(rows, (d * x).sum(axis=1) / total, 1)
    return float(x0), float(slope)


def slanted_edge_mtf(
    image: np.ndarray,
    half_width_px: float = 64.0,
    oversampling: int = 4,
    phases_per_px: int | None = None,
) -> EdgeMtf:
    """The MTF along the normal of the straight edge in ``image`` (see the module docstring).

    image: (H, W) values linear in the irradiance (e.g. DN minus the bias), with one
    straight edge between 1 and 45 degrees from the pixel columns crossing every row (the
    slope lets the rows sample different phases). half_width_px: the ESF is used out to this
    distance from the edge on both sides (px along the normal); it should hold the blur's
    wings, and every pixel's row must reach that far (W >= 2 half_width_px + H |slope| + 2).
    oversampling: k for ISO bins of 1/k px. phases_per_px: N for per-phase bins of an edge
    drawn with slope +-1/N (then ``oversampling`` is not used).
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2 or min(img.shape) < 8 or not np.all(np.isfinite(img)):
        raise SatsightError(
            f"image must be a finite 2-D array of at least 8 x 8 pixels; got shape {img.shape}"
        )
    if not (half_width_px >= 2):
        raise SatsightError(f"half_width_px must be >= 2 px; got {half_width_px!r}")
    h, w = img.shape
    x0, slope = _edge_line(img, half_width_px)
    if not (math.tan(math.radians(1.0)) <= abs(slope) <= 1.0):
        raise SatsightError(
            f"the edge is {math.degrees(math.atan(slope)):.2f} deg from the pixel columns; the "
            "edge method needs 1 to 45 deg (ISO 12233 suggests about 5 deg)"
        )
    y, x = np.indices(img.shape)
    if phases_per_px is not None:
        if isinstance(phases_per_px, bool) or int(phases_per_px) != phases_per_px:
            raise SatsightError(f"phases_per_px must be a whole number; got {phases_per_px!r}")
        n = int(phases_per_px)
        if abs(abs(slope) * n - 1.0) > _LATTICE_SLOPE_TOLERANCE:
            raise SatsightError(
                f"the edge's fitted slope {slope:.5f} is not +-1/{n}; per-phase bins need an "
                "edge drawn with slope 1/N: pass its N, or use ISO bins (phases_per_px=None)"
            )
        slope, cos = math.copysign(1.0 / n, slope), 1.0 / math.hypot(1.0, 1.0 / n)
        # Pixels x N - y sgn(slope) = q share a phase: their distance to the edge is
        # (q - x0 N) cos / N.
        key = x * n - y * int(math.copysign(1, slope))
        first = math.floor(x0 * n) - math.floor(half_width_px * n / cos)
        count = 2 * math.floor(half_width_px * n / cos) + 1
        spacing_px = cos / n
    else:
        if isinstance(oversampling, bool) or int(oversampling) != oversampling or oversampling < 2:
            raise SatsightError(f"oversampling must be a whole number >= 2; got {oversampling!r}")
        n = int(oversampling)
        cos = math.cos(math.atan(slope))
        distance = (x - (x0 + slope * y)) * cos
        key = np.floor(distance * n).astype(np.int64)
        first = -math.floor(half_width_px * n)
        count = 2 * math.floor(half_width_px * n)
        spacing_px = 1.0 / n
    index = (key - first).ravel()
    inside = (index >= 0) & (index < count)
    filled = np.bincount(index[inside], minlength=count)
    if filled.min() == 0:
        raise SatsightError(
            "some ESF bins within half_width_px of the edge hold no pixel; widen the image "
            f"(W >= 2 half_width_px + H |slope| + 2 = {2 * half_width_px + h * abs(slope) + 2:.0f} "
            f"px) or lower half_width_px; got {w} px"
        )
    esf = np.bincount(index[inside], weights=img.ravel()[inside], minlength=count) / filled
    if esf[-1] < esf[0]:
        esf = esf[::-1]
    if phases_per_px is not None:
        lsf = np.diff(esf)
    else:
        lsf = 0.5 * (esf[2:] - esf[:-2])
    lsf = lsf * np.hanning(lsf.size + 2)[1:-1]
    spectrum = np.abs(np.fft.rfft(lsf))
    if spectrum[0] <= 0:
        raise SatsightError("the edge has no contrast (the ESF is flat); check the image")
    mtf = spectrum / spectrum[0]
    freq = np.fft.rfftfreq(lsf.size, d=spacing_px)
    if phases_per_px is None:
        delta = 1.0 / n
        mtf = mtf / (np.sinc(freq * delta) * np.sinc(2.0 * freq * delta))
    return EdgeMtf(freq, mtf, math.atan(slope), n if phases_per_px is not None else None, esf)
