"""Debris clouds: sizes follow the truncated breakup power law, centres lie in the shell,
fragments are closed convex hulls of the asked size; merged scenes keep the target's ids."""

from __future__ import annotations

import numpy as np
from scipy.stats import kstest

from satsight.scene.band_reflectance import library_materials
from satsight.scene.objects import (
    DEBRIS_MATERIALS,
    breakup_size_cdf,
    debris_cloud,
    sample_breakup_sizes_m,
)

COUNT = 4000
# Kolmogorov-Smirnov critical value at the 0.1 % level: 1.95 / sqrt(n).
KS_CRITICAL = 1.95 / np.sqrt(COUNT)


def test_sizes_follow_the_breakup_power_law() -> None:
    bounds = (0.05, 2.0)
    sizes = sample_breakup_sizes_m(COUNT, bounds, np.random.default_rng(1))
    assert sizes.min() >= bounds[0] and sizes.max() <= bounds[1]
    statistic = kstest(sizes, lambda x: breakup_size_cdf(x, bounds)).statistic
    assert statistic < KS_CRITICAL
    # The median of N(>L) ~ L^-1.6 truncated: closed form from the CDF.
    lo, hi, a = bounds[0], bounds[1], 1.6
    median = (lo**-a - 0.5 * (lo**-a - hi**-a)) ** (-1 / a)
    # Order-statistic standard error of the median: 1 / (2 f(m) sqrt(n)); 4 sigma.
    pdf = a * median ** (-a - 1) / (lo**-a - hi**-a)
    assert abs(np.median(sizes) - median) < 4 / (2 * pdf * np.sqrt(COUNT))


def test_a_debris_cloud_lies_in_its_shell_with_fragments_of_their_size() -> None:
    center = np.array([1.0, -2.0, 0.5])
    pool = library_materials(DEBRIS_MATERIALS)
    cloud = debris_cloud("d", 40, (0.1, 0.5), (3.0, 6.0), center, pool, seed=4)
    r = np.linalg.norm(cloud.centers_m - center, axis=1)
    assert r.min() >= 3.0 and r.max() <= 6.0
    mesh = cloud.mesh
    assert len(mesh.part_names) == 40
    for k in range(40):
        faces = mesh.faces[mesh.face_part_index == k]
        v = mesh.vertices_m
        # A closed outward surface: the divergence theorem gives a positive volume.
        volume = np.einsum("ij,ij->i", v[faces[:, 0]], np.cross(v[faces[:, 1]], v[faces[:, 2]]))
        assert volume.sum() / 6 > 0
        points = v[np.unique(faces)]
        assert np.all(np.linalg.norm(points - cloud.centers_m[k], axis=1) <= cloud.sizes_m[k] * 3)
