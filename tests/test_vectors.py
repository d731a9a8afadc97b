"""satsight.vectors: lengths, unit vectors and angles against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from satsight.vectors import angle_between_rad, norm, unit

EPS = np.finfo(np.float64).eps


def test_norm_and_unit_of_known_vectors():
    v = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0]])
    np.testing.assert_array_equal(norm(v), [5.0, 2.0])
    np.testing.assert_allclose(unit(v), [[0.6, 0.8, 0.0], [0.0, 0.0, -1.0]], rtol=0, atol=EPS)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-6, 0.3, np.pi / 2, 2.5, np.pi - 1e-9, np.pi])
@pytest.mark.parametrize("dimension", [2, 3, 5])
def test_angle_between_rotated_unit_vectors_is_the_rotation_angle(angle, dimension):
    # u = e0, v = cos(a) e0 + sin(a) e1, both scaled: the angle is a to rounding, also near
    # 0 and pi, where arccos(u . v) would be off by ~sqrt(eps) ~ 1e-8 rad.
    u = np.zeros(dimension)
    v = np.zeros(dimension)
    u[0] = 2.5
    v[0], v[1] = 7.0 * np.cos(angle), 7.0 * np.sin(angle)
    assert angle_between_rad(u, v) == pytest.approx(angle, rel=8 * EPS, abs=8 * EPS)


def test_angle_between_rows_and_zero_vector():
    u = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    v = np.array([[0.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(angle_between_rad(u, v), [np.pi / 2, np.pi, 0.0], atol=4 * EPS)
