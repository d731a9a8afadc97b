"""Small frames for the sensor chain's tests: a chain on a small high-resolution camera
and rendered images built from radiance arrays."""

from __future__ import annotations

import dataclasses

import numpy as np

from satsight.camera.pinhole import PinholeCamera
from satsight.render.buffers import RadianceImage, margin_pixels_xy
from satsight.sensor.chain import SensorChain
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.exposure_rule import ExposureRule
from satsight.sensor.optics import Optics

BAND_NM = (450.0, 900.0)


def sensor_chain(
    exposure: ExposureRule | None = None, size_px: tuple[int, int] = (96, 80), **detector
) -> SensorChain:
    camera = PinholeCamera.high_resolution().with_size(*size_px)
    return SensorChain(
        camera=camera,
        optics=Optics.for_preset("high_resolution"),
        detector=DetectorParameters(pixel_pitch_m=camera.pixel_pitch_m, **detector),
        band_nm=BAND_NM,
        exposure=exposure or ExposureRule(),
        camera_seed=3,
    )


def radiance_image(radiance_rgb: np.ndarray) -> RadianceImage:
    h, w = radiance_rgb.shape[:2]
    hit = radiance_rgb.any(axis=2)
    return RadianceImage(
        radiance_w_m2_sr=radiance_rgb.astype(np.float32),
        depth_m=np.where(hit, np.float32(1000.0), np.float32(0.0)),
        part_id=hit.astype(np.uint16),
        normals_cam=np.zeros((h, w, 3), np.float32),
    )


def with_ring(radiance_rgb: np.ndarray, margin_px: int) -> RadianceImage:
    """A frame whose radiance comes from the middle of a larger (H + 2m, W + 2m, 3) scene,
    with the rest as its margin ring (the renderer's ``margin_pixels_xy`` order)."""
    m = margin_px
    h, w = radiance_rgb.shape[0] - 2 * m, radiance_rgb.shape[1] - 2 * m
    x, y = margin_pixels_xy(w, h, m)
    inner = radiance_image(radiance_rgb[m : m + h, m : m + w])
    return dataclasses.replace(
        inner, margin_px=m, margin_radiance_w_m2_sr=radiance_rgb[y + m, x + m].astype(np.float32)
    )
