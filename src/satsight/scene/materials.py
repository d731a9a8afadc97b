"""Surface materials in the metallic / roughness / IOR / alpha model (paper section 3.3).

Each material is what the renderer needs to evaluate the paper's GGX model (Eq. 18-20):

* ``kd = (1 - M) * base_color``              diffuse albedo per channel
* ``ks = M * base_color + (1 - M) * F0``     specular reflectance at normal incidence
* ``F0 = ((IOR - 1) / (IOR + 1))^2``         Fresnel reflectance of the dielectric part
* ``alpha_ggx = R^2``                        GGX width from perceptual roughness R

``alpha`` here is the *opacity* of the paper (1 opaque, 0 fully transparent), not the GGX width.

The Phong models (paper Eq. 16-17) take their coefficients from the same material:
``kd = (1 - M) base (1 - F0)`` (the diffuse light that is not reflected at the interface, so
``kd + ks <= 1``), ``ks`` as above, and a gloss exponent ``g`` from the roughness unless
given: ``g = (1 / alpha_ggx^2 - 1) / 2``. That is the Blinn-Phong exponent matching a
microfacet width, ``2 / alpha^2 - 2`` (Walter et al. 2007, EGSR, section 5.2), divided by 4
because the paper's lobe is around the mirror direction (cos^g beta with beta ~ 2 theta_h),
and clamped to [1, 10^4]. The improved model's extra exponents ``a``, ``b`` and ``c`` are
assumed values until fitted to measured BRDF data. A material may instead carry explicit
Phong coefficients (``Material.phong``, a ``PhongCoefficients``), e.g. fitted to its own GGX
BRDF by ``satsight.brdf.reference_fit``; the Phong models then use those, and the GGX model
is unaffected.

The values of ``FIRST_MATERIALS`` are representative first choices for the part types of
the paper's IceSat-2 model (section 3.3 and Fig. 11); the only published figure used is
aluminium's F0 = 0.91 (paper section 3.3). The others are assumptions until the material
library is fitted to measured BRDF data, and say so in their ``source`` field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError

MIN_GLOSS_EXPONENT = 1.0
MAX_GLOSS_EXPONENT = 1.0e4
MAX_LOBE_DECAY_B = 20.0
MAX_DIFFUSE_EXPONENT_C = 4.0


@dataclass(frozen=True)
class PhongCoefficients:
    """Explicit coefficients of the Phong models (paper Eq. 16-17) for one material.

    kd_rgb, ks_rgb: diffuse and specular reflectances per channel in [0, 1] with
    kd + ks <= 1 per channel (energy conservation, see docs/design.md). gloss_exponent_g in
    [1, 1e4]; fresnel_exponent_a in [0, 1], lobe_decay_b in [0, 20], diffuse_exponent_c in
    [0, 4]: the improved model's exponents (the original Phong model ignores them; with
    a = b = c = 0 the improved model is Phong). source: where the values come from.
    """

    kd_rgb: tuple[float, float, float]
    ks_rgb: tuple[float, float, float]
    gloss_exponent_g: float
    fresnel_exponent_a: float = 0.0
    lobe_decay_b: float = 0.0
    diffuse_exponent_c: float = 0.0
    source: str = "assumed"

    def __post_init__(self) -> None:
        kd = tuple(float(v) for v in np.asarray(self.kd_rgb, dtype=np.float64).ravel())
        ks = tuple(float(v) for v in np.asarray(self.ks_rgb, dtype=np.float64).ravel())
        object.__setattr__(self, "kd_rgb", kd)
        object.__setattr__(self, "ks_rgb", ks)
        for key in ("gloss_exponent_g", "fresnel_exponent_a", "lobe_decay_b", "diffuse_exponent_c"):
            object.__setattr__(self, key, float(getattr(self, key)))
        problems = []
        for key, values in (("kd_rgb", kd), ("ks_rgb", ks)):
            if len(values) != 3 or not all(0.0 <= v <= 1.0 for v in values):
                problems.append(f"{key} must be 3 values in [0, 1], got {values}")
        if len(kd) == 3 and len(ks) == 3:
            total = [d + s for d, s in zip(kd, ks, strict=True)]
            if max(total) > 1.0 + KD_KS_SUM_TOLERANCE:
                problems.append(
                    f"kd + ks must be <= 1 per channel (energy conservation), got "
                    f"{tuple(round(t, 6) for t in total)}"
                )
        problems += _shape_problems(
            self.gloss_exponent_g,
            self.fresnel_exponent_a,
            self.lobe_decay_b,
            self.diffuse_exponent_c,
        )
        if problems:
            raise SatsightError("Phong coefficients: " + "; ".join(problems))


KD_KS_SUM_TOLERANCE = 1e-9
"""Rounding allowed above kd + ks = 1 (a fit's kd = t (1 - s), ks = t s with t <= 1)."""


def _shape_problems(g: float | None, a: float, b: float, c: float) -> list[str]:
    """Range errors of the Phong shape parameters g (None: derived), a, b, c."""
    problems = []
    if g is not None and not (MIN_GLOSS_EXPONENT <= g <= MAX_GLOSS_EXPONENT):
        problems.append(
            f"gloss_exponent_g must be in [{MIN_GLOSS_EXPONENT:g}, {MAX_GLOSS_EXPONENT:g}], got {g}"
        )
    if not (0.0 <= a <= 1.0):
        problems.append(f"fresnel_exponent_a must be in [0, 1], got {a}")
    if not (0.0 <= b <= MAX_LOBE_DECAY_B):
        problems.append(f"lobe_decay_b must be in [0, {MAX_LOBE_DECAY_B:g}], got {b}")
    if not (0.0 <= c <= MAX_DIFFUSE_EXPONENT_C):
        problems.append(f"diffuse_exponent_c must be in [0, {MAX_DIFFUSE_EXPONENT_C:g}], got {c}")
    return problems


@dataclass(frozen=True)
class Material:
    """A surface material.

    base_color_rgb: linear reflectance per channel in [0, 1]. metallic M and roughness R in
    [0, 1]. ior: index of refraction >= 1 of the dielectric part (1 gives no specular
    reflection). alpha: opacity in [0, 1]. source: where the values come from.
    gloss_exponent_g (None: from the roughness), fresnel_exponent_a, lobe_decay_b,
    diffuse_exponent_c: the Phong models' shape parameters. phong: explicit Phong
    coefficients that replace all of the derived ones (``phong_coefficients``), or None.
    """

    name: str
    base_color_rgb: tuple[float, float, float]
    metallic: float
    roughness: float
    ior: float
    alpha: float = 1.0
    source: str = "assumed"
    gloss_exponent_g: float | None = None
    fresnel_exponent_a: float = 0.5
    lobe_decay_b: float = 0.5
    diffuse_exponent_c: float = 1.0
    phong: PhongCoefficients | None = None

    def __post_init__(self) -> None:
        color = tuple(float(c) for c in self.base_color_rgb)
        object.__setattr__(self, "base_color_rgb", color)
        problems = []
        if len(color) != 3 or not all(0.0 <= c <= 1.0 for c in color):
            problems.append(f"base_color_rgb must be 3 values in [0, 1], got {color}")
        for key in ("metallic", "roughness", "alpha"):
            value = getattr(self, key)
            if not (0.0 <= value <= 1.0):
                problems.append(f"{key} must be in [0, 1], got {value}")
        if not (self.ior >= 1.0 and math.isfinite(self.ior)):
            problems.append(f"ior must be a finite number >= 1, got {self.ior}")
        problems += _shape_problems(
            self.gloss_exponent_g,
            self.fresnel_exponent_a,
            self.lobe_decay_b,
            self.diffuse_exponent_c,
        )
        if self.phong is not None and not isinstance(self.phong, PhongCoefficients):
            problems.append(f"phong must be PhongCoefficients or None, got {type(self.phong)}")
        if problems:
            raise SatsightError(f"material '{self.name}': " + "; ".join(problems))

    @property
    def f0(self) -> float:
        """Fresnel reflectance at normal incidence of the dielectric part, ((n-1)/(n+1))^2."""
        return ((self.ior - 1.0) / (self.ior + 1.0)) ** 2

    @property
    def kd_rgb(self) -> np.ndarray:
        """Diffuse albedo (1 - M) * base colour (paper Eq. 18)."""
        return (1.0 - self.metallic) * np.asarray(self.base_color_rgb)

    @property
    def ks_rgb(self) -> np.ndarray:
        """Specular reflectance at normal incidence M * base + (1 - M) * F0 (paper Eq. 18)."""
        return self.metallic * np.asarray(self.base_color_rgb) + (1.0 - self.metallic) * self.f0

    @property
    def alpha_ggx(self) -> float:
        """GGX distribution width alpha = R^2 (paper Eq. 19)."""
        return self.roughness**2

    @property
    def phong_kd_rgb(self) -> np.ndarray:
        """Diffuse coefficient of the Phong models, (1 - M) base (1 - F0), so kd + ks <= 1."""
        return self.kd_rgb * (1.0 - self.f0)

    @property
    def phong_gloss_exponent(self) -> float:
        """Gloss exponent g of the Phong lobe: given, or matched to the GGX roughness."""
        if self.gloss_exponent_g is not None:
            return float(self.gloss_exponent_g)
        alpha = max(self.alpha_ggx, 1e-6)
        g = 0.5 * (1.0 / alpha**2 - 1.0)
        return float(min(max(g, MIN_GLOSS_EXPONENT), MAX_GLOSS_EXPONENT))

    @property
    def mapped_phong_coefficients(self) -> PhongCoefficients:
        """The Phong coefficients derived from the GGX parameters (module docstring):
        kd = ``phong_kd_rgb``, ks = ``ks_rgb``, g = ``phong_gloss_exponent`` and the
        material's a, b, c."""
        return PhongCoefficients(
            kd_rgb=tuple(self.phong_kd_rgb),
            ks_rgb=tuple(self.ks_rgb),
            gloss_exponent_g=self.phong_gloss_exponent,
            fresnel_exponent_a=self.fresnel_exponent_a,
            lobe_decay_b=self.lobe_decay_b,
            diffuse_exponent_c=self.diffuse_exponent_c,
            source=f"mapped from the GGX parameters of '{self.name}'",
        )

    @property
    def phong_coefficients(self) -> PhongCoefficients:
        """The coefficients the Phong models render with: ``phong`` when given, else
        ``mapped_phong_coefficients``."""
        return self.phong if self.phong is not None else self.mapped_phong_coefficients


def _m(name, rgb, metallic, roughness, ior, alpha=1.0, source="assumed"):
    return Material(name, rgb, metallic, roughness, ior, alpha, source)


FIRST_MATERIALS: dict[str, Material] = {
    m.name: m
    for m in [
        _m("mli_gold", (0.80, 0.56, 0.22), 0.85, 0.35, 1.70),
        _m("mli_silver", (0.90, 0.90, 0.88), 0.90, 0.30, 1.70),
        _m("solar_cell", (0.05, 0.07, 0.20), 0.0, 0.12, 1.52),
        _m("panel_substrate", (0.30, 0.30, 0.32), 0.2, 0.60, 1.50),
        _m("white_paint", (0.85, 0.85, 0.82), 0.0, 0.80, 1.50),
        _m("black_crinkle", (0.03, 0.03, 0.03), 0.0, 0.90, 1.50),
        _m("black_metal", (0.05, 0.05, 0.05), 1.0, 0.45, 1.50),
        _m(
            "brushed_aluminium",
            (0.91, 0.92, 0.92),
            1.0,
            0.30,
            1.50,
            source="F0 = 0.91 of aluminium: paper section 3.3; roughness assumed",
        ),
        _m("titanium_hinge", (0.54, 0.50, 0.45), 1.0, 0.40, 1.50),
        _m("optical_lens", (0.02, 0.02, 0.03), 0.0, 0.02, 1.46),
        _m("cfrp", (0.05, 0.05, 0.05), 0.0, 0.50, 1.60),
        _m("instrument_grey", (0.45, 0.45, 0.45), 0.3, 0.50, 1.50),
        _m("antenna_white", (0.80, 0.80, 0.78), 0.0, 0.70, 1.50),
        _m(
            "lambert_white",
            (1.0, 1.0, 1.0),
            0.0,
            1.0,
            1.0,
            source="ideal Lambertian reflector: IOR 1 gives F0 = 0, so no specular lobe",
        ),
    ]
}

DEFAULT_MATERIAL_NAME = "instrument_grey"


def resolve_material(name: str, library: dict[str, Material] | None = None) -> Material:
    """Look a material up by name, with a message listing the known ones when missing."""
    lib = FIRST_MATERIALS if library is None else library
    try:
        return lib[name]
    except KeyError:
        raise SatsightError(
            f"unknown material '{name}'; known materials: {', '.join(sorted(lib))}"
        ) from None
