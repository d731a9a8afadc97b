"""The catalogue stars of one planned frame on its focal plane, trailed by the camera's turn.

A camera that turns at ``omega_cam_rad_s`` (inertial, camera axes; ``PoseTrack``) during an
exposure T sees a star's direction d move as d(tau) = Exp(-w tau) d(0)
(``satsight.poses.pose_rates``): each star's photons are spread over its path, as the mean of
``n`` stamps at the midpoints of n equal strata of the exposure, each with 1/n of them
(n = ceil(path / 0.5 px), at most 32, the target's rule in ``satsight.render.motion``). The
labels keep the star's position at mid-exposure.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from satsight.constants import EARTH_EQUATORIAL_RADIUS_M, MOON_MEAN_RADIUS_M
from satsight.poses.pose_rates import rotation_from_vector
from satsight.poses.track import PoseTrack
from satsight.render.motion import MAX_TIME_SAMPLES, SAMPLE_SPACING_PX
from satsight.sensor.chain import SensorChain, blur_radius_px


def star_trail_offsets_s(
    omega_cam_rad_s: np.ndarray, focal_length_px: float, exposure_time_s: float
) -> np.ndarray:
    """(n,) instants (s from mid-exposure) of the stamps of a star trail: a camera turn of
    |w| T rad moves a star by at most ~ |w| T f px near the image centre."""
    path_px = float(np.linalg.norm(omega_cam_rad_s)) * exposure_time_s * focal_length_px
    n = min(MAX_TIME_SAMPLES, max(1, math.ceil(path_px / SAMPLE_SPACING_PX)))
    return ((np.arange(n) + 0.5) / n - 0.5) * exposure_time_s


def add_frame_stars(
    sensor: SensorChain,
    track: PoseTrack,
    index: int,
    irradiance_w_m2: np.ndarray,
    object_mask: np.ndarray,
    center_cam_m: np.ndarray,
    exposure_time_s: float,
    v_mag_limit: float,
    earth_atmosphere_margin_m: float,
    R_cam_from_planned: np.ndarray | None = None,
) -> dict:
    """Add the catalogue stars in view of frame ``index`` to its focal-plane irradiance, in
    place, hidden behind the target (its mask), the Earth (with the atmosphere margin) and
    the Moon, trailed over the exposure (module docstring); return the frame's star labels
    (each star's catalogue id, pixel position at mid-exposure, V magnitude, mean photons
    reaching the detector over the exposure and the detector's quantum efficiency for its
    spectrum). Each star's photons are weighted by its own QE over the chain's
    (``SensorChain.star_quantum_efficiency_ratio``), so the detector counts its electrons
    at its own QE. R_cam_from_planned: the camera's turn from the plan's camera frame (a
    randomised roll); the plan's directions and rates are turned by it (default none)."""
    from satsight.sensor.star_catalog import load_star_catalog
    from satsight.sensor.star_field import (
        DEFAULT_STAMP_RADIUS_PX,
        star_photon_counts,
        stars_in_view,
    )
    from satsight.sensor.star_stamps import star_photons_image

    camera = sensor.camera
    R = np.eye(3) if R_cam_from_planned is None else np.asarray(R_cam_from_planned)
    omega_cam_rad_s = R @ track.omega_cam_rad_s[index]
    offsets = star_trail_offsets_s(omega_cam_rad_s, camera.focal_length_px, exposure_time_s)
    trail_px = float(np.linalg.norm(omega_cam_rad_s)) * exposure_time_s
    trail_px *= camera.focal_length_px
    # Stamps wide enough for the defocus disc and the jitter (and half the trail); stars
    # are kept (and labelled) only when their stamp reaches the frame.
    stamp_radius_px = DEFAULT_STAMP_RADIUS_PX + blur_radius_px(sensor.optics, camera.pixel_pitch_m)

    def sphere(direction: np.ndarray, distance_m: float, radius_m: float):
        return center_cam_m + (R @ direction) * distance_m, radius_m

    spheres = [
        sphere(
            track.earth_from_target_cam[index],
            track.earth_distance_m[index],
            EARTH_EQUATORIAL_RADIUS_M + earth_atmosphere_margin_m,
        ),
        sphere(track.moon_from_target_cam[index], track.moon_distance_m[index], MOON_MEAN_RADIUS_M),
    ]
    stars = stars_in_view(
        load_star_catalog(v_mag_limit),
        R @ track.R_cam_from_gcrs(index),
        camera,
        track.epoch_utc[index],
        track.camera_velocity_gcrs_m_s[index],
        occluding_spheres_cam=spheres,
        object_mask=object_mask,
        band_nm=sensor.band_nm,
        margin_px=stamp_radius_px + 0.5 + 0.5 * trail_px,
    )
    qe_ratio = sensor.star_quantum_efficiency_ratio(stars.temperature_k)
    scale = sensor.photons_to_irradiance_factor(exposure_time_s) * qe_ratio / len(offsets)
    directions = camera.ray_directions_cam(np.stack([stars.x_px, stars.y_px], axis=-1))
    for tau in offsets:
        moved = stars
        if tau != 0.0:
            turn = rotation_from_vector(-omega_cam_rad_s * tau)
            uv = camera.project(directions @ turn.T)
            moved = dataclasses.replace(stars, x_px=uv[:, 0], y_px=uv[:, 1])
        star_photons_image(
            moved,
            object_mask.shape,
            sensor.optics,
            camera.pixel_pitch_m,
            exposure_time_s,
            sensor.band_nm,
            stamp_radius_px,
            out=irradiance_w_m2,
            scale=scale,
        )
    labels = stars.labels()
    photons = star_photon_counts(stars.photon_flux_m2_s, sensor.optics, exposure_time_s)
    star_qe = sensor.detector.star_quantum_efficiency(sensor.band_nm, stars.temperature_k)
    for record, count, qe in zip(labels["stars"], photons, star_qe, strict=True):
        record["photons"] = float(count)
        record["quantum_efficiency"] = float(qe)
    labels["star_trail_samples"] = len(offsets)
    return labels
