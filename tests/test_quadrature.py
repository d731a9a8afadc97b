"""satsight.quadrature: the trapezoid rule and Gauss-Legendre nodes against closed forms."""

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


@pytest.mark.parametrize("n", [2, 7, 64])
def test_gauss_legendre_is_exact_to_degree_2n_minus_1_and_kept_read_only(n):
    """n nodes integrate x^k over [-1, 1] exactly (2 / (k + 1) for even k, 0 for odd) up to
    k = 2n - 1; the rule is computed once and cannot be changed by a caller."""
    from satsight.quadrature import gauss_legendre

    nodes, weights = gauss_legendre(n)
    for k in range(2 * n):
        exact = 2.0 / (k + 1) if k % 2 == 0 else 0.0
        assert np.dot(weights, nodes**k) == pytest.approx(exact, abs=1e-13)
    assert gauss_legendre(n) is gauss_legendre(n)
    with pytest.raises(ValueError, match="read-only"):
        nodes[0] = 0.0
