"""The frame kernel's taps from their definition, for tests.

``frame_kernel`` designs its taps by an inverse 2-D DFT of the designed response K = H / (S S)
sampled on a grid of the Nyquist square. Here the same taps come from the integral that
defines them, the Fourier coefficients of K over the square,

    k[my, mx] = p^2 integral of K(fx, fy) cos(2 pi p fx mx) cos(2 pi p fy my) dfx dfy,

(K is real and even in fx and fy) by Gauss-Legendre quadrature on [0, 1 / (2 p)] per axis,
then cut to the kernel's size and divided by their sum, as the design does. No DFT, no
grid, no quadrant folding: an independent computation of the same numbers.
"""

from __future__ import annotations

import math

import numpy as np

from satsight.sensor.mtf import render_sampling_otf, system_otf_2d
from satsight.sensor.optics import Optics


def frame_kernel_taps(
    optics: Optics,
    wavelengths_m: np.ndarray,
    pixel_pitch_m: float,
    size_px: int,
    supersampling: int = 1,
    samples_per_pixel: int = 1,
    nodes: int = 384,
) -> np.ndarray:
    """(size_px, size_px) taps summing to 1, rows my, columns mx, centre at size_px // 2."""
    p = pixel_pitch_m
    half = size_px // 2
    x, w = np.polynomial.legendre.leggauss(nodes)
    f = (x + 1.0) * (0.25 / p)  # nodes on [0, 1 / (2 p)], cycles/m
    wf = w * (0.25 / p)
    response = system_otf_2d(f[None, :], f[:, None], optics, p, wavelengths_m)  # [fy, fx]
    s = render_sampling_otf(f, p, supersampling, samples_per_pixel)
    response = response / (s[:, None] * s[None, :])
    m = np.arange(-half, half + 1)
    # Twice the half-axis integral: the integrand is even in each frequency.
    c = 2.0 * wf[:, None] * np.cos(2.0 * math.pi * p * f[:, None] * m[None, :])
    taps = p**2 * (c.T @ response @ c)
    return taps / taps.sum()


def edge_and_corner_loss(taps: np.ndarray) -> tuple[float, float]:
    """Fractions of a uniform scene's light that a frame's edge pixel (mid-row) and corner
    pixel lose when nothing lies beyond the frame: the taps whose source falls outside it.

    Edge: the taps one side of the centre column, sum over mx = 1 .. r of the column sums.
    Corner: all but the quadrant (axes included) that stays inside. ``taps`` is symmetric.
    """
    r = taps.shape[1] // 2
    edge = float(taps.sum(axis=0)[r + 1 :].sum())
    corner = 1.0 - float(taps[: r + 1, : r + 1].sum())
    return edge, corner
