"""The Earth's light samples drawn from its radiance table (``satsight.render.earth_table``):
the cells' weights against the Earth's luminance (numpy twin), the sampler against its
own density, and the density normalised over the cone."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from satsight.constants import EARTH_MEAN_RADIUS_M
from satsight.lighting.scene_bodies import earth_body
from satsight.render import earth_table
from satsight.render.earth_table import COLUMNS, ROWS, UNIFORM_SHARE

LUMINANCE_RGB = np.array([0.2126, 0.7152, 0.0722])
Z_LIMIT = 4.0


def _earth(sun):
    """A spherical Earth 500 km below the origin (-z), albedo 0.3, the Sun along ``sun``."""
    center = np.array([0.0, 0.0, -(EARTH_MEAN_RADIUS_M + 500e3)])
    sun = np.asarray(sun, dtype=float) / np.linalg.norm(sun)
    return earth_body(center, np.eye(3), 0.3, sun, 1361.0, shape="sphere")


def test_cell_weights_are_the_earths_luminance_plus_the_uniform_share() -> None:
    """With the terminator across the cone (Sun on the horizon), each cell's weight is its
    mean luminance over 2 x 2 points (the numpy twin) plus UNIFORM_SHARE x the mean: dark
    cells keep the uniform share, lit ones more."""
    earth = _earth([1.0, 0.0, 0.05])
    axis, tangent, bitangent, one_minus, weights = earth_table.cell_weights(earth, np.zeros(3))
    np.testing.assert_allclose(axis, [0.0, 0.0, -1.0], atol=1e-12)
    rows, cols = np.divmod(np.arange(ROWS * COLUMNS), COLUMNS)
    luminance = np.zeros(ROWS * COLUMNS)
    for fu in (0.25, 0.75):
        for fv in (0.25, 0.75):
            d = earth_table.cell_directions(axis, tangent, bitangent, one_minus, rows, cols, fu, fv)
            assert np.all(d @ axis >= 1.0 - one_minus - 1e-12)  # inside the cone
            luminance += earth.radiance_along(np.zeros(3), d) @ LUMINANCE_RGB
    np.testing.assert_allclose(weights, luminance + UNIFORM_SHARE * luminance.mean(), rtol=1e-12)
    dark = luminance == 0.0
    assert 0.2 < dark.mean() < 0.8  # the terminator crosses the cone
    assert weights[dark].min() == pytest.approx(UNIFORM_SHARE * luminance.mean())


def test_samples_follow_the_table_and_its_density(llvm_variant) -> None:
    """60 000 samples: each direction in the cone, its density the one ``pdf`` gives (but
    at cell boundaries), the
    cells' counts as the table's probabilities (chi-square over rows), and the density
    integrates to 1 over the cone (uniform directions, within 4 standard errors)."""
    import mitsuba as mi

    earth = _earth([1.0, 0.2, 0.3])
    table = earth_table.earth_table(earth, np.zeros(3))
    n = 60_000
    rng = np.random.default_rng(9)
    u1, u2 = (mi.Float(rng.random(n, dtype=np.float32)) for _ in range(2))
    direction, density = earth_table.sample(table, u1, u2)
    d = np.stack([direction.x.numpy(), direction.y.numpy(), direction.z.numpy()], axis=1)
    one_minus = float(table.one_minus_cos.numpy()[0])
    axis = np.array([0.0, 0.0, -1.0])
    assert np.all(d @ axis >= 1.0 - one_minus * (1.0 + 1e-5))
    # The same density but where float rounding puts a direction on a cell boundary
    # into the neighbouring cell (a few in 10^5).
    same = np.isclose(density.numpy(), earth_table.pdf(table, direction).numpy(), rtol=2e-3)
    assert same.mean() > 0.9995
    pmf = table.pmf.numpy().astype(np.float64).reshape(ROWS, COLUMNS)
    row = np.minimum(((1.0 - d @ axis) / one_minus * ROWS).astype(int), ROWS - 1)
    counts = np.bincount(row, minlength=ROWS)
    assert stats.chisquare(counts, n * pmf.sum(axis=1) / pmf.sum()).pvalue > 1e-4
    # Uniform directions in the cone: E[pdf] x solid angle = 1.
    cone_sr = 2.0 * math.pi * one_minus
    v1, v2 = rng.random(n), rng.random(n)
    one_minus_t = v1 * one_minus
    sin_t = np.sqrt(one_minus_t * (2.0 - one_minus_t))
    tangent, bitangent = earth_table.cone_frame(axis)
    uniform = (
        (1.0 - one_minus_t)[:, None] * axis
        + (sin_t * np.cos(2 * math.pi * v2))[:, None] * tangent
        + (sin_t * np.sin(2 * math.pi * v2))[:, None] * bitangent
    )
    values = earth_table.pdf(table, mi.Vector3f(*(mi.Float(c) for c in uniform.T))).numpy()
    values = values.astype(np.float64) * cone_sr
    assert abs(values.mean() - 1.0) < Z_LIMIT * values.std(ddof=1) / math.sqrt(n)


def test_without_an_earth_the_table_is_uniform(llvm_variant) -> None:
    table = earth_table.earth_table(None, np.zeros(3))
    np.testing.assert_allclose(table.pmf.numpy(), 1.0 / (ROWS * COLUMNS), rtol=1e-5)
