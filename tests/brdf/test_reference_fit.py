"""Phong models fitted to a material's GGX BRDF (``satsight.brdf.reference_fit``), and
explicit Phong coefficients in the renderer (``Material.phong``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from builders import plate_parts
from satsight.brdf.models import ggx_brdf
from satsight.brdf.parameters import ALBEDO_TOLERANCE, max_directional_albedo
from satsight.brdf.reference_fit import (
    fit_phong_to_ggx,
    ggx_reference_table,
    reference_grid,
)
from satsight.camera.pinhole import PinholeCamera
from satsight.errors import SatsightError
from satsight.frames.rigid import look_at_cam_from_body
from satsight.lighting.light_field import LightField
from satsight.render import phong
from satsight.render.renderer import Renderer
from satsight.render.settings import DIRECT_SUN_ONLY
from satsight.scene.materials import FIRST_MATERIALS, Material, PhongCoefficients
from satsight.scene.mesh import merge_parts

GLOSSY = FIRST_MATERIALS["mli_silver"]  # metallic 0.9, roughness 0.3: a strong lobe
ROUGH = FIRST_MATERIALS["instrument_grey"]  # a dielectric-metal mixture, roughness 0.5
# GGX with metallic 0 and IOR 1: F = 0 everywhere, so f = base / pi (Lambert) exactly.
LAMBERT = Material("lambert_colour", (0.6, 0.4, 0.2), metallic=0.0, roughness=0.7, ior=1.0)


def test_grid_weights_integrate_the_radiance_weight():
    """The weights are a quadrature of cos^2(theta_i) cos(theta_o) over incidence
    (mu_i in [cos 85 deg, 1], one azimuth: d omega_i / (2 pi) = d mu_i) and the viewer
    hemisphere (int cos(theta_o) d omega_o = pi): the sum is
    int mu^2 d mu * pi = pi (1 - mu_lo^3) / 3."""
    mu_lo = math.cos(math.radians(85.0))
    expected = math.pi * (1.0 - mu_lo**3) / 3.0
    for width in (0.002, 0.2, 2.0):
        grid = reference_grid(width)
        assert np.all(grid.weight > 0.0) and np.all(grid.wo[:, 2] > 0.0)
        # the horizon cut of the mirror-centred grid limits the accuracy (~1e-3)
        assert grid.weight.sum() == pytest.approx(expected, rel=5e-3)


def test_reference_table_holds_the_ggx_values():
    table = ggx_reference_table(GLOSSY)
    assert table.n_channels == 3 and table.channel_names == ("R", "G", "B")
    expected = ggx_brdf(
        table.wi(), table.wo(), np.asarray(GLOSSY.base_color_rgb)[table.channel], 0.9, 0.3, 1.7
    )
    np.testing.assert_allclose(table.brdf_per_sr, expected, rtol=1e-9, atol=1e-12)
    with pytest.raises(SatsightError, match="masking"):
        ggx_reference_table(GLOSSY, masking="beckmann")


@pytest.mark.parametrize("material", [GLOSSY, ROUGH], ids=lambda m: m.name)
def test_fitted_coefficients_are_valid_and_conserve_energy(llvm_variant, material):
    """Each fit gives coefficients inside the renderer's ranges (PhongCoefficients and the
    renderer's own parameter checks accept them) whose directional albedo is <= 1."""
    result = fit_phong_to_ggx(material)
    assert set(result.fits) == {"improved_phong", "phong"}
    for model, fit in result.fits.items():
        c = fit.coefficients
        assert np.all(np.add(c.kd_rgb, c.ks_rgb) <= 1.0)
        params = dict(kd=np.asarray(c.kd_rgb), ks=np.asarray(c.ks_rgb), g=c.gloss_exponent_g)
        if model == "improved_phong":
            params.update(a=c.fresnel_exponent_a, b=c.lobe_decay_b, c=c.diffuse_exponent_c)
            phong.validate_improved_phong_parameters(**params)
        else:
            assert (c.fresnel_exponent_a, c.lobe_decay_b, c.diffuse_exponent_c) == (0, 0, 0)
            phong.validate_phong_parameters(**params)
        albedo, _ = max_directional_albedo(model, params)
        assert albedo <= 1.0 + ALBEDO_TOLERANCE
        assert fit.fit.max_albedo <= 1.0 + ALBEDO_TOLERANCE
        assert 0.0 < fit.weighted_relative_rms < 1.0
        # and the renderer builds its tables from them
        fitted = result.material_for(model)
        assert fitted.phong == c and fitted.base_color_rgb == material.base_color_rgb


def test_improved_phong_fits_a_glossy_ggx_at_least_as_well_as_phong():
    """Improved Phong contains Phong (a = b = c = 0), so its optimum cannot be worse; the
    starts differ, so allow the optimiser a 1 % margin."""
    fits = fit_phong_to_ggx(GLOSSY).fits
    improved, plain = fits["improved_phong"], fits["phong"]
    assert improved.weighted_relative_rms <= 1.01 * plain.weighted_relative_rms


def test_a_lambertian_ggx_material_fits_to_kd_equal_base_and_no_lobe():
    """GGX with metallic 0 and IOR 1 is f = base / pi, inside both Phong families (ks = 0,
    c = 0): the fit is exact up to the optimiser's tolerance. least_squares stops at a
    relative cost change of 1e-8, i.e. a relative residual of ~1e-4; kd errs by at most
    that times kd's sensitivity (pi f / f = 1), so 1e-3 on kd and ks leaves a margin."""
    assert np.allclose(
        ggx_brdf([[0.3, 0.0, 0.95]], [[-0.5, 0.2, 0.84]], np.array([0.6]), 0.0, 0.7, 1.0),
        0.6 / math.pi,
    )
    result = fit_phong_to_ggx(LAMBERT)
    for model, fit in result.fits.items():
        c = fit.coefficients
        np.testing.assert_allclose(c.kd_rgb, LAMBERT.base_color_rgb, atol=1e-3, err_msg=model)
        np.testing.assert_allclose(c.ks_rgb, 0.0, atol=1e-3, err_msg=model)
        assert fit.weighted_relative_rms < 1e-3
        if model == "improved_phong":
            assert c.diffuse_exponent_c < 1e-2


def test_fits_are_cached_per_material_values():
    first = fit_phong_to_ggx(ROUGH)
    renamed = dataclasses.replace(ROUGH, name="another_name")
    again = fit_phong_to_ggx(renamed)
    assert again.fits["phong"].fit is first.fits["phong"].fit
    assert again.material.name == "another_name"


def test_phong_coefficients_are_validated():
    with pytest.raises(SatsightError, match="kd \\+ ks"):
        PhongCoefficients((0.6, 0.6, 0.6), (0.5, 0.1, 0.1), 10.0)
    with pytest.raises(SatsightError, match="gloss_exponent_g"):
        PhongCoefficients((0.1, 0.1, 0.1), (0.1, 0.1, 0.1), 0.5)
    with pytest.raises(SatsightError, match="lobe_decay_b"):
        PhongCoefficients((0.1, 0.1, 0.1), (0.1, 0.1, 0.1), 10.0, lobe_decay_b=21.0)
    with pytest.raises(SatsightError, match="phong must be"):
        Material("m", (0.5, 0.5, 0.5), 0.0, 0.5, 1.5, phong={"kd_rgb": (0.1, 0.1, 0.1)})
    m = FIRST_MATERIALS["mli_gold"]
    assert m.phong is None and m.phong_coefficients == m.mapped_phong_coefficients
    np.testing.assert_array_equal(m.phong_coefficients.kd_rgb, m.phong_kd_rgb)
    np.testing.assert_array_equal(m.phong_coefficients.ks_rgb, m.ks_rgb)


@pytest.mark.parametrize(("brdf", "c"), [("phong", 0.0), ("improved_phong", 1.0)])
def test_explicit_coefficients_render_their_lambert_plate(llvm_variant, brdf, c):
    """A plate whose explicit coefficients are kd, ks = 0 shows L = kd E cos^(1 + c) / pi
    (the material's own, mapped kd would be 1: lambert_white)."""
    kd = (0.3, 0.5, 0.7)
    coefficients = PhongCoefficients(kd, (0.0, 0.0, 0.0), 5.0, diffuse_exponent_c=c)
    material = dataclasses.replace(FIRST_MATERIALS["lambert_white"], phong=coefficients)
    v, f = plate_parts()
    mesh = merge_parts([("plate", material.name, v, f)], {material.name: material})
    theta = math.radians(40.0)
    e_w_m2 = 1000.0
    light = LightField.sun_only(np.array([math.sin(theta), 0.0, math.cos(theta)]), e_w_m2)
    camera = PinholeCamera(3.0, 15e-6, 32, 32)  # the plate fills the view at 1 km
    pose = look_at_cam_from_body(
        np.array([0.0, -300.0, 1000.0]), np.zeros(3), up_hint_body=np.array([0, 1.0, 0])
    )
    image = Renderer(mesh, DIRECT_SUN_ONLY.with_(brdf=brdf), llvm_variant).render(
        camera, pose, light
    )
    seen = image.radiance_w_m2_sr[image.object_mask]
    expected = np.array(kd) * e_w_m2 * math.cos(theta) ** (1.0 + c) / math.pi
    assert len(seen) == 32 * 32
    np.testing.assert_allclose(seen, np.broadcast_to(expected, seen.shape), rtol=2e-4)


def test_explicit_mapped_coefficients_render_as_the_mapping(llvm_variant):
    """Giving every material its mapped coefficients explicitly changes nothing, textured
    parts (solar cells, radiator strips) included: bit for bit."""
    from satsight.config.scenario import Scenario

    scenario = Scenario.model_validate(
        {
            "name": "explicit",
            "target": {"procedural": {"satellite_class": "two_wings", "seed": 2}},
            "frames": [{"distance_km": 0.06}],
        }
    )
    mesh = scenario.target.build()
    assert mesh.part_textures  # the textured path is exercised
    explicit = dataclasses.replace(
        mesh,
        materials={
            k: dataclasses.replace(m, phong=m.mapped_phong_coefficients)
            for k, m in mesh.materials.items()
        },
    )
    light = LightField.sun_only(np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93]), 1e3)
    camera = PinholeCamera(0.3, 15e-6, 48, 48)
    pose = look_at_cam_from_body(
        mesh.center_m + np.array([20.0, 30.0, 40.0]), mesh.center_m, np.array([0, 0, 1.0])
    )
    for brdf in ("phong", "improved_phong"):
        settings = DIRECT_SUN_ONLY.with_(brdf=brdf)
        a = Renderer(mesh, settings, llvm_variant).render(camera, pose, light)
        b = Renderer(explicit, settings, llvm_variant).render(camera, pose, light)
        assert a.object_mask.sum() > 100
        assert a.radiance_w_m2_sr.tobytes() == b.radiance_w_m2_sr.tobytes(), brdf
