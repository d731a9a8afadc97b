"""A frame's draws turned into the stages' inputs: materials, the sensor chain, the Sun's
direction and the rotations of the pose group. Pure functions of the draws."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from satsight.constants import EARTH_MEAN_RADIUS_M
from satsight.frames.quaternion import matrix_from_quaternion, quaternion_from_axis_angle
from satsight.frames.rigid import RigidTransform
from satsight.randomization.draws import (
    EarthDraw,
    MaterialDraw,
    PoseDraw,
    SensorDraw,
    SunDraw,
    cap_angle_rad,
)
from satsight.randomization.ranges import EARTH_BEHIND_CAP_FRACTION
from satsight.scene.materials import Material
from satsight.sensor.chain import SensorChain
from satsight.vectors import unit

#: Bounds of the varied material values: GGX roughness below 0.02 is a mirror the
#: renderer's sampling treats poorly; dielectrics below n = 1.05 reflect almost nothing.
MIN_ROUGHNESS = 0.02
MIN_IOR = 1.05
#: The detector's largest PRNU (``DetectorParameters``' own bound).
MAX_PRNU_FRACTION = 0.2


def varied_material(material: Material, draw: MaterialDraw) -> Material:
    """``material`` with its roughness, base colour and IOR moved by ``draw`` (clipped:
    roughness to [MIN_ROUGHNESS, 1], each colour channel to 1, IOR to >= MIN_IOR)."""
    return dataclasses.replace(
        material,
        roughness=float(np.clip(material.roughness * draw.roughness_scale, MIN_ROUGHNESS, 1.0)),
        base_color_rgb=tuple(
            float(min(1.0, c * draw.base_color_scale)) for c in material.base_color_rgb
        ),
        ior=float(max(MIN_IOR, material.ior + draw.ior_shift)),
    )


def varied_materials(
    materials: Mapping[str, Material], draws: Mapping[str, MaterialDraw]
) -> dict[str, Material]:
    """Every material of ``materials``, those with a draw varied (``varied_material``)."""
    return {
        name: varied_material(m, draws[name]) if name in draws else m
        for name, m in materials.items()
    }


def swapped_name(candidates: tuple[str, ...], draw: MaterialDraw) -> str | None:
    """The library material (of ``candidates``, a family's others) that replaces the
    material, or None (no swap drawn, or no candidate)."""
    if not (draw.swap and candidates):
        return None
    return candidates[min(int(draw.swap_choice * len(candidates)), len(candidates) - 1)]


def material_record(material: Material, draw: MaterialDraw, swapped: str | None = None) -> dict:
    """The varied values of one material for the labels (SI, dimensionless); swapped: the
    library material it was replaced by first, if any."""
    return {
        "library_material": swapped,
        "roughness_scale": draw.roughness_scale,
        "base_color_scale": draw.base_color_scale,
        "ior_shift": draw.ior_shift,
        "roughness": material.roughness,
        "base_color_rgb": list(material.base_color_rgb),
        "ior": material.ior,
    }


def varied_sensor(sensor: SensorChain, draw: SensorDraw) -> SensorChain:
    """The sensor chain with the detector's read noise, gain and PRNU scaled, the optics'
    defocus and jitter replaced, and the exposure factor set (the frame kernel is fitted
    again for the new optics)."""
    detector = dataclasses.replace(
        sensor.detector,
        read_noise_e=sensor.detector.read_noise_e * draw.read_noise_scale,
        conversion_gain_e_per_dn=sensor.detector.conversion_gain_e_per_dn * draw.gain_scale,
        prnu_fraction=min(MAX_PRNU_FRACTION, sensor.detector.prnu_fraction * draw.prnu_scale),
    )
    optics = dataclasses.replace(
        sensor.optics,
        defocus_blur_diameter_m=draw.defocus_blur_diameter_m,
        jitter_rms_rad=draw.jitter_rms_rad,
    )
    return dataclasses.replace(
        sensor, detector=detector, optics=optics, exposure_factor=draw.exposure_factor
    )


def sensor_record(sensor: SensorChain, draw: SensorDraw) -> dict:
    """The varied sensor values for the labels (SI)."""
    return {
        "exposure_factor": draw.exposure_factor,
        "read_noise_e": sensor.detector.read_noise_e,
        "conversion_gain_e_per_dn": sensor.detector.conversion_gain_e_per_dn,
        "prnu_fraction": sensor.detector.prnu_fraction,
        "defocus_blur_diameter_m": sensor.optics.defocus_blur_diameter_m,
        "jitter_rms_rad": sensor.optics.jitter_rms_rad,
    }


def perpendicular_basis(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) making (e1, e2, d) a right-handed orthonormal basis with
    d the unit ``direction``; e1 lies in the plane of d and +z (of +x when d is along z)."""
    d = unit(np.asarray(direction, dtype=np.float64))
    reference = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e2 = unit(np.cross(d, reference))
    e1 = np.cross(e2, d)
    return e1, e2


def jittered_direction(direction: np.ndarray, draw: SunDraw) -> np.ndarray:
    """The unit ``direction`` turned by the draw's angle towards its azimuth (about the
    direction, from ``perpendicular_basis``'s e1)."""
    d = unit(np.asarray(direction, dtype=np.float64))
    if draw.direction_jitter_rad == 0.0:
        return d
    e1, e2 = perpendicular_basis(d)
    theta, phi = draw.direction_jitter_rad, draw.jitter_azimuth_rad
    return unit(math.cos(theta) * d + math.sin(theta) * (math.cos(phi) * e1 + math.sin(phi) * e2))


def earth_behind_direction(
    line_of_sight_body: np.ndarray, altitude_m: float, draw: EarthDraw
) -> tuple[np.ndarray, float]:
    """(unit direction of the Earth's centre from the target, body frame; its angle off
    the line of sight, rad) for an Earth moved behind the target: the angle uniform over
    the spherical cap of EARTH_BEHIND_CAP_FRACTION x the Earth's angular radius seen from
    ``altitude_m`` about ``line_of_sight_body`` (unit, camera to target), towards the
    draw's azimuth."""
    sin_radius = EARTH_MEAN_RADIUS_M / (EARTH_MEAN_RADIUS_M + altitude_m)
    cap = EARTH_BEHIND_CAP_FRACTION * math.asin(sin_radius)
    theta = cap_angle_rad(draw.behind_offset_u, cap)
    turned = SunDraw(1.0, theta, draw.behind_azimuth_rad)
    return jittered_direction(line_of_sight_body, turned), theta


def roll_transform(draw: PoseDraw) -> RigidTransform:
    """rolled_cam_from_cam: the camera turned by ``roll_rad`` about its boresight (+z)."""
    c, s = math.cos(draw.roll_rad), math.sin(draw.roll_rad)
    # The camera turns by +roll about +z, so a fixed point's coordinates turn by -roll.
    R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return RigidTransform(R, np.zeros(3))


def attitude_jitter_transform(draw: PoseDraw, center_body_m: np.ndarray) -> RigidTransform:
    """body_from_jittered: the target turned by ``attitude_jitter_rad`` about
    ``jitter_axis_body`` through its box centre ``center_body_m`` (a point of the turned
    target at x in its own frame lies at c + R (x - c) in the planned body frame)."""
    R = matrix_from_quaternion(
        quaternion_from_axis_angle(np.asarray(draw.jitter_axis_body), draw.attitude_jitter_rad)
    )
    c = np.asarray(center_body_m, dtype=np.float64)
    return RigidTransform(R, c - R @ c)


def pose_record(draw: PoseDraw) -> dict:
    return {
        "roll_rad": draw.roll_rad,
        "attitude_jitter_rad": draw.attitude_jitter_rad,
        "jitter_axis_body": list(draw.jitter_axis_body),
    }
