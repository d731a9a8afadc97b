"""How a frame is rendered: reflection model, lighting representation, light paths, samples.

One ``RenderSettings`` object carries every choice that changes the radiance of a frame;
the scenario's ``render:`` block builds it, and ``satsight ablate`` varies it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

from satsight.errors import SatsightError

BrdfModel = Literal["ggx", "improved_phong", "phong"]
GgxMasking = Literal["schlick", "smith"]
SunRepresentation = Literal["delta", "sh"]
EnvironmentMode = Literal["sampled", "sh", "unshadowed", "off"]
TextureFilter = Literal["mip", "stochastic"]

BRDF_MODELS: tuple[str, ...] = ("ggx", "improved_phong", "phong")
GGX_MASKINGS: tuple[str, ...] = ("schlick", "smith")
SUN_REPRESENTATIONS: tuple[str, ...] = ("delta", "sh")
ENVIRONMENT_MODES: tuple[str, ...] = ("sampled", "sh", "unshadowed", "off")
TEXTURE_FILTERS: tuple[str, ...] = ("mip", "stochastic")
SH_ORDER_RANGE = (2, 8)
MAX_BOUNCES = 16
MAX_TRANSPARENT_LAYERS = 8


@dataclass(frozen=True)
class RenderSettings:
    """Every choice that changes a frame's radiance.

    brdf: ``"ggx"`` (metallic/roughness/IOR, paper Eq. 18-20), ``"improved_phong"``
    (paper Eq. 17) or ``"phong"`` (paper Eq. 16). ggx_masking: ``"schlick"`` (the paper's
    Schlick-GGX, k = (R+1)^2/8) or ``"smith"`` (exact separable Smith GGX).
    sh_order: highest SH degree L of the environment light field (paper: 4).
    sun: ``"delta"`` (exact collimated source with a shadow ray) or ``"sh"`` (the Sun's
    delta expanded into SH of order ``sh_order`` and added to the environment, as the
    paper's Eq. 10). environment: ``"sampled"`` (the light field's bodies, the Earth and
    the Moon, traced as sunlit ellipsoids by BRDF-sampled and body-sampled rays combined
    by multiple importance sampling: exact earthshine, shadowed by the target itself; a
    light field without bodies falls back to its SH expansion), ``"sh"`` (the paper's
    method: BRDF-sampled rays pick up the SH expansion of order ``sh_order``, clamped at
    0, shadowed by the target), ``"unshadowed"`` (diffuse part from the SH irradiance,
    no self-shadowing; specular part sampled) or ``"off"``. Every mode shows the bodies
    behind the target.
    bounces: inter-reflections between parts after the first surface (0 = direct light
    only). samples_per_pixel: light paths per pixel and sub-pixel position.
    supersampling: s gives s x s stratified sub-pixel positions; labels always come from
    the pixel centre. max_transparent_layers: surfaces with opacity alpha < 1 a ray may
    pass through before it stops. indirect_min_roughness: path regularisation (Kaplanyan &
    Dachsbacher 2013): at surfaces reached by a bounce, the roughness is at least this
    (0 turns it off), which turns the rare, very bright Sun caustics through mirror-like
    parts into soft glossy inter-reflection instead of single-pixel outliers.
    integrate_footprint: render a target that is small on the image (its projected box
    under 128 / supersampling px across) again on a fine grid over that box, so that its
    pixels hold its flux integrated over their area (``satsight.render.footprint``): a
    sub-pixel target keeps its signal instead of vanishing or filling a pixel.
    texture_filter: how a camera ray's hit averages the textures over its footprint
    (``satsight.render.target_geometry``): ``"mip"`` looks up the mip level of the
    footprint, which averages the texture's *values* (smooth, but normal and
    metallic-roughness maps do not enter the radiance linearly, so the expected radiance
    depends on the footprint); ``"stochastic"`` looks up the full-size texture at a random
    point of the footprint, so the expected radiance is the radiance averaged over it
    (unbiased, with the texture's sub-pixel contrast as noise).
    """

    brdf: BrdfModel = "ggx"
    ggx_masking: GgxMasking = "schlick"
    sh_order: int = 4
    sun: SunRepresentation = "delta"
    environment: EnvironmentMode = "sampled"
    bounces: int = 2
    samples_per_pixel: int = 1
    supersampling: int = 1
    max_transparent_layers: int = 4
    indirect_min_roughness: float = 0.2
    integrate_footprint: bool = True
    texture_filter: TextureFilter = "mip"
    sunlit_sampling: bool = True
    light_samples: int = 2

    def __post_init__(self) -> None:
        problems = []
        for key, allowed in (
            ("brdf", BRDF_MODELS),
            ("ggx_masking", GGX_MASKINGS),
            ("sun", SUN_REPRESENTATIONS),
            ("environment", ENVIRONMENT_MODES),
            ("texture_filter", TEXTURE_FILTERS),
        ):
            if getattr(self, key) not in allowed:
                problems.append(f"{key} must be one of {', '.join(allowed)}")
        lo, hi = SH_ORDER_RANGE
        if not (isinstance(self.sh_order, int) and lo <= self.sh_order <= hi):
            problems.append(f"sh_order must be an integer in [{lo}, {hi}]")
        if not (isinstance(self.bounces, int) and 0 <= self.bounces <= MAX_BOUNCES):
            problems.append(f"bounces must be an integer in [0, {MAX_BOUNCES}]")
        if not (isinstance(self.samples_per_pixel, int) and 1 <= self.samples_per_pixel):
            problems.append("samples_per_pixel must be an integer >= 1")
        if not (isinstance(self.supersampling, int) and 1 <= self.supersampling <= 8):
            problems.append("supersampling must be an integer in [1, 8]")
        if not (1 <= self.max_transparent_layers <= MAX_TRANSPARENT_LAYERS):
            problems.append(f"max_transparent_layers must be in [1, {MAX_TRANSPARENT_LAYERS}]")
        if not (0.0 <= self.indirect_min_roughness <= 1.0):
            problems.append("indirect_min_roughness must be in [0, 1]")
        count = self.light_samples
        if isinstance(count, bool) or not (isinstance(count, int) and 1 <= count <= 64):
            problems.append("light_samples must be an integer in [1, 64]")
        for key in ("integrate_footprint", "sunlit_sampling"):
            if not isinstance(getattr(self, key), bool):
                problems.append(f"{key} must be true or false")
        if problems:
            raise SatsightError("render settings: " + "; ".join(problems))

    @property
    def passes(self) -> int:
        """Light paths traced per pixel: supersampling^2 x samples_per_pixel."""
        return self.supersampling**2 * self.samples_per_pixel

    def with_(self, **changes) -> RenderSettings:
        """A copy with some settings changed (validated again)."""
        return replace(self, **changes)


DIRECT_SUN_ONLY = RenderSettings(environment="off", bounces=0)
