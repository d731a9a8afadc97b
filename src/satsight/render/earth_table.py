"""Light samples of the Earth drawn in proportion to its radiance.

Seen from a low orbit the Earth fills a cone of ~65 degrees half-angle whose radiance
varies tenfold between ocean and cloud, and drops to zero past the terminator. Directions
uniform in that cone give a shaded part lit by earthshine alone an on/off estimate: a
sample that lands on a cloud is worth ten that land on the sea. So the cone is cut into
``ROWS`` x ``COLUMNS`` cells of equal solid angle (rows uniform in cos theta about the cone's
axis, columns in azimuth), each frame the Earth's luminance is evaluated at 2 x 2 points
of each cell (numpy, ``SceneBody.radiance_along``, from the render-space origin), and a
light sample picks a cell with probability proportional to that luminance plus
``UNIFORM_SHARE`` times the mean (a defensive mixture: half the samples uniform over the
cone, as before, since the table knows nothing of the shading point's horizon, which
may hide the Earth's bright part), then a point uniform in its solid angle. The density
of a direction is the cell's probability over its solid angle; directions outside the
cone, and the sliver a shading point off the origin sees beyond it, have density 0 and
are left to the BRDF's samples (multiple importance sampling keeps the mean).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.constants import REC709_LUMINANCE_RGB
from satsight.lighting.scene_bodies import SceneBody

ROWS, COLUMNS = 32, 64
#: Each cell's weight is its luminance plus this multiple of the cells' mean (1: half the
#: samples uniform over the cone).
UNIFORM_SHARE = 1.0
_SUB = (0.25, 0.75)  # 2 x 2 evaluation points per cell, in cell units
_TWO_PI = 2.0 * math.pi
_LUMINANCE_RGB = np.array(REC709_LUMINANCE_RGB)


@dataclass(frozen=True, eq=False)
class EarthTable:
    """One frame's table (Dr.Jit values; the scalars opaque).

    axis, tangent, bitangent: the cone's orthonormal frame (body frame). one_minus_cos:
    1 - cos of the cone's half-angle. cdf: (ROWS x COLUMNS,) cumulative probability of the
    cells, row-major, last 1. pmf: each cell's probability.
    """

    axis: object
    tangent: object
    bitangent: object
    one_minus_cos: object
    cdf: object
    pmf: object


def cone_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit ``axis`` to a right-handed orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    tangent = np.cross(helper, axis)
    tangent /= np.linalg.norm(tangent)
    return tangent, np.cross(axis, tangent)


def cell_directions(axis, tangent, bitangent, one_minus_cos: float, rows, cols, fu, fv):
    """Unit directions (N, 3) at fractional positions (fu, fv) of cells (rows, cols)."""
    one_minus = (rows + fu) / ROWS * one_minus_cos
    cos_t = 1.0 - one_minus
    sin_t = np.sqrt(np.maximum(one_minus * (2.0 - one_minus), 0.0))
    phi = _TWO_PI * (cols + fv) / COLUMNS
    return (
        cos_t[:, None] * axis
        + (sin_t * np.cos(phi))[:, None] * tangent
        + (sin_t * np.sin(phi))[:, None] * bitangent
    )


def cell_weights(earth: SceneBody, origin_body_m: np.ndarray) -> tuple:
    """(axis, tangent, bitangent, 1 - cos alpha, weights (ROWS x COLUMNS,)) of the Earth's
    cone seen from ``origin_body_m``: each cell's mean luminance over 2 x 2 points plus the
    uniform share (module docstring). Uniform weights where the Earth is dark from there."""
    to_center = earth.center_body_m - origin_body_m
    distance = float(np.linalg.norm(to_center))
    axis = to_center / distance
    sin2 = min(1.0, (earth.bounding_radius_m / distance) ** 2)
    one_minus_cos = sin2 / (1.0 + math.sqrt(1.0 - sin2))
    tangent, bitangent = cone_frame(axis)
    rows, cols = np.divmod(np.arange(ROWS * COLUMNS), COLUMNS)
    luminance = np.zeros(ROWS * COLUMNS)
    for fu in _SUB:
        for fv in _SUB:
            d = cell_directions(axis, tangent, bitangent, one_minus_cos, rows, cols, fu, fv)
            luminance += earth.radiance_along(origin_body_m, d) @ _LUMINANCE_RGB
    mean = luminance.mean()
    weights = np.ones_like(luminance) if mean <= 0.0 else luminance + UNIFORM_SHARE * mean
    return axis, tangent, bitangent, one_minus_cos, weights


def earth_table(earth: SceneBody | None, origin_body_m: np.ndarray) -> EarthTable:
    """The frame's table (a placeholder cone along +z with uniform cells without an
    Earth, whose light samples then carry zero irradiance)."""
    import drjit as dr
    import mitsuba as mi

    if earth is None:
        axis, tangent, bitangent = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
        one_minus_cos, weights = 1.0, np.ones(ROWS * COLUMNS)
    else:
        axis, tangent, bitangent, one_minus_cos, weights = cell_weights(earth, origin_body_m)
    cdf = (np.cumsum(weights) / weights.sum()).astype(np.float32)
    cdf[-1] = 1.0
    pmf = np.diff(cdf.astype(np.float64), prepend=0.0).astype(np.float32)
    vectors = [mi.Vector3f(*(float(c) for c in v)) for v in (axis, tangent, bitangent)]
    span = mi.Float(float(one_minus_cos))
    dr.make_opaque(*vectors, span)
    return EarthTable(*vectors, span, mi.Float(cdf), mi.Float(pmf))


def sample(table: EarthTable, u1, u2):
    """A direction from the table (unit, body frame) from two uniform numbers, and its
    solid-angle density."""
    import drjit as dr
    import mitsuba as mi

    cdf, pmf = table.cdf, table.pmf
    cell = dr.binary_search(0, ROWS * COLUMNS - 1, lambda i: dr.gather(mi.Float, cdf, i) <= u1)
    cell = dr.minimum(mi.UInt32(cell), ROWS * COLUMNS - 1)
    p_cell = dr.gather(mi.Float, pmf, cell)
    start = dr.gather(mi.Float, cdf, cell) - p_cell
    # u1's position within its cell's share: uniform again in [0, 1).
    fu = dr.clip((u1 - start) / dr.maximum(p_cell, 1e-30), 0.0, 0.99999994)
    row, col = cell // COLUMNS, cell % COLUMNS
    one_minus = (mi.Float(row) + fu) * (1.0 / ROWS) * table.one_minus_cos
    cos_t = 1.0 - one_minus
    sin_t = dr.safe_sqrt(one_minus * (2.0 - one_minus))
    sin_p, cos_p = dr.sincos(_TWO_PI / COLUMNS * (mi.Float(col) + u2))
    direction = cos_t * table.axis + sin_t * (cos_p * table.tangent + sin_p * table.bitangent)
    return direction, p_cell * (ROWS * COLUMNS / _TWO_PI) / table.one_minus_cos


def pdf(table: EarthTable, direction):
    """Solid-angle density with which ``sample`` picks the unit ``direction``."""
    import drjit as dr
    import mitsuba as mi

    cos_t = dr.dot(direction, table.axis)
    # 1 - cos from the sine (sin^2 / (1 + cos)): exact for the small cone of a far Earth.
    one_minus = dr.squared_norm(dr.cross(direction, table.axis)) / (1.0 + cos_t)
    one_minus = dr.select(cos_t > 0.0, one_minus, 1.0 - cos_t)
    x = one_minus / table.one_minus_cos
    inside = x < 1.0
    row = mi.UInt32(dr.clip(dr.floor(x * ROWS), 0, ROWS - 1))
    phi = dr.atan2(dr.dot(direction, table.bitangent), dr.dot(direction, table.tangent))
    phi = dr.select(phi < 0.0, phi + _TWO_PI, phi)
    col = mi.UInt32(dr.clip(dr.floor(phi * (COLUMNS / _TWO_PI)), 0, COLUMNS - 1))
    p_cell = dr.gather(mi.Float, table.pmf, row * COLUMNS + col, inside)
    return dr.select(inside, p_cell * (ROWS * COLUMNS / _TWO_PI) / table.one_minus_cos, 0.0)
