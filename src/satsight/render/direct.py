"""Direct sunlight only: the radiative renderer with no environment and no inter-reflection.

``DirectRenderer`` is ``satsight.render.renderer.Renderer`` with
``RenderSettings(environment="off", bounces=0)`` and the GGX model, taking a ``SunLight``:
per pixel a primary ray, the first surface it hits, a shadow ray towards the Sun and the
BRDF. It is what the geometry and radiometry checks of the render core use.
"""

from __future__ import annotations

from satsight.camera.pinhole import PinholeCamera
from satsight.frames.rigid import RigidTransform
from satsight.lighting.light_field import LightField, SunLight
from satsight.render.buffers import RadianceImage
from satsight.render.renderer import Renderer
from satsight.render.settings import DIRECT_SUN_ONLY
from satsight.scene.mesh import TargetMesh


class DirectRenderer(Renderer):
    """Renders one target mesh under direct sunlight; reuse it for every frame.

    mesh: the target in its body frame. variant: ``"auto"``, ``"llvm_ad_rgb"`` or
    ``"cuda_ad_rgb"`` (see ``satsight.render.backend``).
    """

    def __init__(self, mesh: TargetMesh, variant: str = "auto") -> None:
        super().__init__(mesh, DIRECT_SUN_ONLY, variant)

    def render(  # type: ignore[override]
        self,
        camera: PinholeCamera,
        cam_from_body: RigidTransform,
        sun: SunLight,
        supersampling: int = 1,
    ) -> RadianceImage:
        """Render one frame.

        camera: intrinsics and image size. cam_from_body: pose of the target in the camera
        frame. sun: direction (body frame) and irradiance. supersampling: s gives s x s
        stratified rays per pixel for the radiance; labels (depth, masks, normals) always
        come from the ray through the pixel centre.
        """
        if supersampling != self.settings.supersampling:
            self.settings = self.settings.with_(supersampling=supersampling)
        light = LightField.sun_only(sun.direction_body, sun.irradiance_w_m2)
        return super().render(camera, cam_from_body, light)
