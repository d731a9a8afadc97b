"""Direction warps and local-frame functions shared by the reflection models, in Dr.Jit.

Conventions of every BRDF module in ``satsight.render``: directions are unit vectors in the
local shading frame, whose normal is +z; ``wi`` points towards the light, ``wo`` towards
the viewer, both away from the surface. A warp maps a point ``u`` of the unit square
(``mi.Point2f``) to a direction, and its ``*_pdf`` partner gives the density of that
direction per unit solid angle (sr^-1).

All functions work with the arrays of the current Mitsuba variant (``mi.Float``,
``mi.Vector3f``, ...) and therefore run on both the LLVM and the CUDA backend. Parameters
such as the lobe exponent are arrays too: every lane may have its own value.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

INV_PI = 1.0 / math.pi
INV_TWO_PI = 0.5 / math.pi
TWO_PI = 2.0 * math.pi


def safe_power(x, exponent):
    """x ** exponent for x >= 0 and any exponent >= 0, with 0 ** 0 = 1 and 0 ** e = 0.

    ``dr.power`` with an array exponent evaluates exp2(e log2 x), which is NaN for x = 0 and
    e = 0; this form keeps the limits that the reflection models need.
    """
    positive = x > 0.0
    value = dr.power(dr.select(positive, x, 1.0), exponent)
    return dr.select(positive, value, dr.select(exponent == 0.0, 1.0, 0.0))


def mirror_local(v):
    """Mirror direction of v about the local normal +z: (-x, -y, z)."""
    return mi.Vector3f(-v.x, -v.y, v.z)


def reflect(v, n):
    """Mirror direction of the unit vector v about the unit axis n: 2 (v.n) n - v."""
    return 2.0 * dr.dot(v, n) * n - v


def frame_around(axis):
    """Orthonormal frame whose third axis is the unit vector ``axis`` (``mi.Frame3f``).

    Mitsuba builds the two tangents branch-free after Duff et al. 2017, "Building an
    Orthonormal Basis, Revisited" (JCGT 6(1)). ``frame.to_world(v)`` maps a vector given
    in coordinates around ``axis`` to the local shading frame.
    """
    return mi.Frame3f(axis)


def square_to_cosine_hemisphere(u):
    """Cosine-weighted direction on the upper hemisphere (pdf cos(theta) / pi)."""
    return mi.warp.square_to_cosine_hemisphere(u)


def cosine_hemisphere_pdf(v):
    """Density (sr^-1) of ``square_to_cosine_hemisphere``: max(v.z, 0) / pi."""
    return dr.maximum(v.z, 0.0) * INV_PI


def square_to_phong_lobe(u, exponent):
    """Direction around +z with density (g + 1) / (2 pi) cos^g(beta) over the hemisphere.

    beta is the angle to +z and g = ``exponent`` >= 0. Inverting the marginal CDF of
    cos(beta) gives cos(beta) = u.x ** (1 / (g + 1)), azimuth 2 pi u.y (Lafortune & Willems
    1994, "Using the modified Phong reflectance model for physically based rendering",
    section 4). sin(beta) is formed as sqrt((1 - c)(1 + c)), which keeps its relative
    precision for the narrow lobes of large g.
    """
    cos_beta = dr.exp2(dr.log2(dr.maximum(u.x, 1e-30)) / (exponent + 1.0))
    cos_beta = dr.minimum(cos_beta, 1.0)
    sin_beta = dr.sqrt(dr.maximum((1.0 - cos_beta) * (1.0 + cos_beta), 0.0))
    sin_phi, cos_phi = dr.sincos(TWO_PI * u.y)
    return mi.Vector3f(sin_beta * cos_phi, sin_beta * sin_phi, cos_beta)


def phong_lobe_pdf(cos_beta, exponent):
    """Density (sr^-1) of ``square_to_phong_lobe`` at a direction with cos(beta) to the axis."""
    return (exponent + 1.0) * INV_TWO_PI * safe_power(dr.maximum(cos_beta, 0.0), exponent)


def sample_phong_lobe(axis, u, exponent):
    """Direction drawn from the Phong lobe ``square_to_phong_lobe`` around a unit axis."""
    return frame_around(axis).to_world(square_to_phong_lobe(u, exponent))
