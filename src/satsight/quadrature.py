"""Quadrature rules used in several places: the trapezoid rule over tabulated spectra (QE
curve, reflectance) and Gauss-Legendre nodes, computed once per order."""

from __future__ import annotations

from functools import cache

import numpy as np


def trapezoid(y: np.ndarray, x: np.ndarray) -> float:
    """Trapezoid-rule integral of samples ``y`` at increasing abscissae ``x`` (1-D), as
    sum of (y_i + y_{i+1}) / 2 (x_{i+1} - x_i) in that order."""
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


@cache
def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The n Gauss-Legendre nodes on [-1, 1] and their weights (``numpy.polynomial.legendre
    .leggauss``), read-only and kept: finding them takes about 2.5 ms at 64 nodes, which the
    light field of every frame paid twice."""
    nodes, weights = np.polynomial.legendre.leggauss(int(n))
    nodes.flags.writeable = False
    weights.flags.writeable = False
    return nodes, weights
