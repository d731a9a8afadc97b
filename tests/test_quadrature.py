"""satsight.quadrature: the trapezoid rule against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from satsight.quadrature import trapezoid


def test_exact_for_a_linear_function_on_an_uneven_grid():
    x = np.array([0.0, 0.3, 1.1, 2.0, 3.7])
    assert trapezoid(2.0 * x + 1.0, x) == pytest.approx(3.7**2 + 3.7, rel=1e-15)


def test_error_of_a_parabola_is_the_closed_form():
    # On n equal steps h over [0, 1], the rule overestimates the integral of x^2 by h^2 / 6.
    n = 50
    x = np.linspace(0.0, 1.0, n + 1)
    h = 1.0 / n
    assert trapezoid(x**2, x) == pytest.approx(1.0 / 3.0 + h**2 / 6.0, rel=1e-13)
