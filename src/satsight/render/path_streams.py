"""The random numbers of the renderer's light paths.

Each pixel has a per-frame random shift (PCG32 seeded by a TEA hash of the frame seed and
the pixel index) of a Kronecker (R_d) low-discrepancy sequence over its passes, so the
passes of one pixel are stratified in every dimension. Decisions that need no
stratification (opacity, shadow and bounce rays through transparent parts) draw from a
PCG32 per path and stream segment.
"""

from __future__ import annotations

import numpy as np

from satsight.render.frame_values import FrameValues


def kronecker_generators(dimensions: int) -> np.ndarray:
    """Generators of the R_d low-discrepancy sequence: 1 / phi_d^(j+1), j < dimensions.

    phi_d is the positive root of x^(d+1) = x + 1 (M. Roberts, "The unreasonable
    effectiveness of quasirandom sequences", 2018).
    """
    phi = 2.0
    for _ in range(64):
        phi = (1.0 + phi) ** (1.0 / (dimensions + 1))
    return np.array([(1.0 / phi) ** (j + 1) % 1.0 for j in range(dimensions)])


def light_segment(depth: int) -> int:
    """Random-stream segment of the body-light shadow ray at path vertex ``depth``."""
    return 1000 + depth


def shading_segment(depth: int) -> int:
    """Random-stream segment of the shadow rays at path vertex ``depth``."""
    return 1 + 2 * depth


def texture_segment() -> int:
    """Random-stream segment of the camera ray's point in its footprint (stochastic texture
    filtering)."""
    return 2000


def sunlit_segment(depth: int) -> int:
    """Random-stream segment of the sunlit-surface sample at path vertex ``depth`` (the
    point, its visibility and its shadow ray)."""
    return 3000 + depth


def bounce_segment(depth: int) -> int:
    """Random-stream segment of the bounce ray that leaves path vertex ``depth``."""
    return 2 + 2 * depth


class PathStreams:
    """The random numbers of paths with up to ``bounces`` + 1 vertices.

    Low-discrepancy dimensions: 2 for the pixel position, 3 per path vertex for the BRDF
    sample, then 3 per path vertex for the body-light sample (from ``light_dims`` on).
    """

    def __init__(self, bounces: int) -> None:
        import drjit as dr
        import mitsuba as mi

        self._mi, self._dr = mi, dr
        self.light_dims = 2 + 3 * (bounces + 1)
        self.n_dims = self.light_dims + 3 * (bounces + 1)
        self._generators = kronecker_generators(self.n_dims)

    def streams(self, frame: FrameValues, idx, pass_index, segment: int):
        """Random numbers of the paths of pixel ``idx`` in pass ``pass_index`` (UInt32):
        (rng, ld) with rng a PCG32 for this path segment and ld(dim) the path's
        low-discrepancy sample in dimension ``dim``.

        The Kronecker sequence's per-pixel random shift is fixed over the frame's passes, so
        the passes of one pixel are stratified; the generators are seeded through TEA
        hashes of (pixel, frame key[, pass, segment]), which decorrelates neighbouring
        pixels and passes. Both depend on the pixel and pass only, so a path continued in a
        later kernel (``segment``) draws the same sequence whatever lane it is on.
        """
        mi, dr = self._mi, self._dr
        key0, key1 = frame.seed_key0, frame.seed_key1
        shift_rng = mi.PCG32(1, mi.sample_tea_64(idx, key0), mi.UInt64(key1))
        shift = [shift_rng.next_float32() for _ in range(self.n_dims)]
        pass_f = mi.Float(pass_index)
        gens = self._generators

        def ld(dim: int):
            x = dr.fma(pass_f, float(gens[dim]), shift[dim])
            # Fractional part, kept below 1 in float32.
            return dr.minimum(x - dr.floor(x), 0.99999994)

        salt = (0x7F4A7C15 + segment * 0x85EBCA6B) & 0xFFFFFFFF
        key = key0 ^ (pass_index * 0x9E3779B9 + salt)
        rng = mi.PCG32(1, mi.sample_tea_64(idx, key), mi.UInt64(key1) + 1)
        return rng, ld
