"""Materials: Fresnel F0, the kd / ks split of paper Eq. 18, GGX width and validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satsight.errors import SatsightError
from satsight.scene.materials import (
    DEFAULT_MATERIAL_NAME,
    FIRST_MATERIALS,
    Material,
    resolve_material,
)

ATOL = 1e-15  # reflectances are numbers in [0, 1]


def material(**overrides) -> Material:
    kwargs = {
        "name": "test",
        "base_color_rgb": (0.5, 0.2, 0.1),
        "metallic": 0.3,
        "roughness": 0.4,
        "ior": 1.5,
        "alpha": 1.0,
    }
    kwargs.update(overrides)
    return Material(**kwargs)


def test_f0_of_glass_like_ior_1_5_is_0_04() -> None:
    # ((1.5 - 1) / (1.5 + 1))^2 = (0.5 / 2.5)^2 = 0.04; exact up to float rounding.
    assert material(ior=1.5).f0 == pytest.approx(0.04, abs=ATOL)


def test_f0_of_ior_1_is_zero_and_grows_with_ior() -> None:
    assert material(ior=1.0).f0 == 0.0
    assert FIRST_MATERIALS["lambert_white"].f0 == 0.0
    assert material(ior=2.0).f0 == pytest.approx(1.0 / 9.0, abs=ATOL)


def test_kd_and_ks_follow_eq_18_for_a_mixed_material() -> None:
    m = material(metallic=0.3, ior=1.5)
    base = np.array([0.5, 0.2, 0.1])
    np.testing.assert_allclose(m.kd_rgb, 0.7 * base, atol=ATOL)
    np.testing.assert_allclose(m.ks_rgb, 0.3 * base + 0.7 * 0.04, atol=ATOL)


def test_pure_metal_has_no_diffuse_and_specular_is_base_colour() -> None:
    m = FIRST_MATERIALS["brushed_aluminium"]
    np.testing.assert_array_equal(m.kd_rgb, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(m.ks_rgb, m.base_color_rgb, atol=ATOL)
    assert m.ks_rgb[0] == pytest.approx(0.91, abs=ATOL)  # aluminium F0, paper section 3.3


def test_pure_dielectric_has_base_colour_diffuse_and_grey_f0_specular() -> None:
    m = material(metallic=0.0, ior=1.5)
    np.testing.assert_allclose(m.kd_rgb, [0.5, 0.2, 0.1], atol=ATOL)
    np.testing.assert_allclose(m.ks_rgb, [0.04] * 3, atol=ATOL)


def test_ggx_width_is_roughness_squared() -> None:
    assert material(roughness=0.4).alpha_ggx == pytest.approx(0.16, abs=ATOL)


def test_first_materials_are_valid_and_keyed_by_name() -> None:
    assert DEFAULT_MATERIAL_NAME in FIRST_MATERIALS
    for name, m in FIRST_MATERIALS.items():
        assert m.name == name
        assert np.all((m.kd_rgb + m.ks_rgb) <= 1.0 + 1e-12), name  # energy: no gain


def test_resolve_material_lists_known_names() -> None:
    assert resolve_material("cfrp") is FIRST_MATERIALS["cfrp"]
    with pytest.raises(SatsightError, match=r"unknown material 'kapton'.*black_crinkle"):
        resolve_material("kapton")
    with pytest.raises(SatsightError, match=r"known materials: x$"):
        resolve_material("y", {"x": material(name="x")})


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"base_color_rgb": (1.2, 0.0, 0.0)}, "base_color_rgb must be 3 values in"),
        ({"base_color_rgb": (0.1, 0.2)}, "base_color_rgb must be 3 values in"),
        ({"metallic": 1.5}, "metallic must be in"),
        ({"roughness": -0.1}, "roughness must be in"),
        ({"alpha": 2.0}, "alpha must be in"),
        ({"ior": 0.9}, "ior must be a finite number >= 1"),
        ({"ior": math.inf}, "ior must be a finite number >= 1"),
        ({"ior": math.nan}, "ior must be a finite number >= 1"),
    ],
)
def test_invalid_values_are_refused_with_the_field_name(overrides: dict, message: str) -> None:
    with pytest.raises(SatsightError, match=f"material 'test': {message}"):
        material(**overrides)


def test_all_problems_are_reported_together() -> None:
    with pytest.raises(SatsightError, match=r"metallic .*; roughness .*; alpha"):
        material(metallic=-1.0, roughness=3.0, alpha=-0.5)
