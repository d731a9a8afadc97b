"""Scenario keys of the camera: a preset with any of its values overridden, its optics,
detector and exposure rule, and an optional second (far) mode.

Non-SI units appear only in the key's name (``pixel_pitch_um``, ``switch_range_km``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from satsight.camera.pinhole import CAMERA_PRESETS, PinholeCamera
from satsight.config.sensor import DetectorConfig, ExposureConfig, OpticsConfig
from satsight.errors import SatsightError
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.optics import Optics


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class FarCameraConfig(_Strict):
    """The second mode of a dual-mode camera (the paper switches from the wide-field to the
    high-resolution camera at 20 km): frames whose range to the target's box centre is
    beyond ``switch_range_km`` are taken with ``preset``'s focal length and optics, on the
    same detector (pixel pitch, image size, fixed pattern, exposure rule)."""

    preset: Literal["high_resolution", "wide_field"] = "wide_field"
    switch_range_km: float = Field(gt=0)


class CameraConfig(_Strict):
    """Camera: a preset, optionally with any of its values overridden, and its sensor.

    ``seed`` fixes the detector's fixed pattern (PRNU and DSNU maps): one camera, one seed.
    ``far``: a second camera mode for frames beyond a range (``FarCameraConfig``).
    """

    preset: Literal["high_resolution", "wide_field"] = "high_resolution"
    focal_length_m: float | None = Field(default=None, gt=0)
    pixel_pitch_um: float | None = Field(default=None, gt=0)
    width_px: int | None = Field(default=None, ge=1, le=32768)
    height_px: int | None = Field(default=None, ge=1, le=32768)
    optics: OpticsConfig = OpticsConfig()
    detector: DetectorConfig = DetectorConfig()
    exposure: ExposureConfig = ExposureConfig()
    seed: int = Field(default=0, ge=0)
    far: FarCameraConfig | None = None

    def far_mode(self) -> CameraConfig | None:
        """The camera of the far frames: this one with the far preset's focal length and
        optics (None without a ``far`` mode)."""
        if self.far is None:
            return None
        return self.model_copy(
            update={
                "preset": self.far.preset,
                "focal_length_m": None,
                "optics": OpticsConfig(),
                "far": None,
            }
        )

    @model_validator(mode="after")
    def _sensor_fits(self) -> CameraConfig:
        try:
            self.build_optics()
        except SatsightError as error:
            raise ValueError(str(error)) from None
        return self

    def build_optics(self) -> Optics:
        return self.optics.build(self.preset, self.build().focal_length_m)

    def build_detector(self) -> DetectorParameters:
        return self.detector.build(self.build().pixel_pitch_m)

    def build(self) -> PinholeCamera:
        base = CAMERA_PRESETS[self.preset]()
        return PinholeCamera(
            focal_length_m=self.focal_length_m or base.focal_length_m,
            pixel_pitch_m=(self.pixel_pitch_um * 1e-6)
            if self.pixel_pitch_um
            else base.pixel_pitch_m,
            width_px=self.width_px or base.width_px,
            height_px=self.height_px or base.height_px,
        )
