"""The trapezoid rule, once: integrals of tabulated spectra (QE curve, reflectance)."""

from __future__ import annotations

import numpy as np


def trapezoid(y: np.ndarray, x: np.ndarray) -> float:
    """Trapezoid-rule integral of samples ``y`` at increasing abscissae ``x`` (1-D), as
    sum of (y_i + y_{i+1}) / 2 (x_{i+1} - x_i) in that order."""
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))
