"""The star field behind the target: which stars a camera sees, where, and how bright.

Chain, for one frame:

1. :func:`stars_in_view`: catalogue directions at the epoch (proper motion,
   :func:`satsight.sensor.star_astrometry.directions_icrs`), aberrated for the camera's
   barycentric velocity (the Earth's, from DE421, plus the camera's geocentric one), rotated
   into the camera frame and projected with the pinhole model; stars behind occluding
   spheres (the Earth with an atmosphere margin, the Moon) or behind the rendered target
   (``object_mask``) are removed; in-band photon flux from V and temperature.
2. :func:`satsight.sensor.star_stamps.star_photons_image`: each star's photons spread over
   the pixels by the pixel-integrated, band-averaged PSF of the optics at its exact
   sub-pixel position.
3. :func:`satsight.sensor.limiting_magnitude.limiting_magnitude`: the faintest V that
   reaches a given SNR with the detector.

Frames: GCRS and ICRS share their axes (no rotation between them); the BCRS -> GCRS
relativistic scale change (~1e-8) is irrelevant for directions. Annual parallax and the
gravitational light deflection by the Sun (< ~16 mas beyond 30 deg from the Sun) are not
applied (nor is the stars' parallax, see :mod:`satsight.sensor.star_catalog`); with that,
the pixel positions agree with astropy's space motion + GCRS transformation to 0.008 px at
f = 3 m and 0.002 px at f = 0.7 m with 15 um pixels (test_star_field).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from skyfield.timelib import Time

from satsight.camera.pinhole import PinholeCamera
from satsight.constants import DEFAULT_BAND_NM
from satsight.ephemeris.sun_moon import ephemeris
from satsight.ephemeris.time import parse_epoch_utc
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import check_band_nm
from satsight.sensor.optics import Optics
from satsight.sensor.star_astrometry import aberrate, directions_icrs
from satsight.sensor.star_catalog import StarCatalog
from satsight.sensor.star_photometry import star_photon_flux_m2_s

DEFAULT_STAMP_RADIUS_PX = 8
"""Half-width of the square pixel stamp of each star (17 x 17 px)."""
DEFAULT_MARGIN_PX = 16.0
"""Stars up to this far outside the image are kept: their PSF wings fall inside."""
N_PSF_WAVELENGTHS = 16
"""Sub-bands over which the diffraction OTF is averaged (weighted by the star's photons)."""
J2000_JD_TT = 2451545.0
PSF_TEMPERATURE_RATIO = 1.25
"""Ratio between neighbouring temperatures at which PSFs are computed and cached."""
DAYS_PER_JULIAN_YEAR = 365.25


# --- time and the observer's velocity --------------------------------------------------------


def _check_time(epoch: Time) -> Time:
    if not isinstance(epoch, Time) or np.ndim(epoch.tt) != 0:
        raise SatsightError(
            f"epoch must be one scalar skyfield Time; got {type(epoch).__name__}. Build it "
            "with satsight.ephemeris.time.parse_epoch_utc('2026-03-20T12:00:00Z')"
        )
    return epoch


def julian_year_tt(epoch: Time) -> float:
    """The epoch as a Julian year on TT: 2000.0 + (JD_TT - 2451545.0) / 365.25."""
    t = _check_time(epoch)
    return 2000.0 + ((float(t.whole) - J2000_JD_TT) + float(t.tt_fraction)) / DAYS_PER_JULIAN_YEAR


def earth_velocity_bcrs_m_s(epoch: Time) -> np.ndarray:
    """(3,) velocity of the Earth's centre relative to the solar-system barycentre, m/s.

    BCRS (ICRS axes), from the JPL DE421 ephemeris through skyfield (about 30 km/s; the
    source of the annual aberration, up to 20.5 arcsec).
    """
    t = _check_time(epoch)
    return np.asarray(ephemeris()["earth"].at(t).velocity.m_per_s, dtype=np.float64).reshape(3)


# --- stars in the field ----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class StarsInView:
    """The M stars that fall on (or just around) the image, (M,) arrays.

    x_px, y_px: pixel position of the star's centre (OpenCV: (0, 0) is the centre of the
    top-left pixel, x right, y down), may lie up to the margin outside the image.
    v_mag: V magnitude. temperature_k: blackbody temperature (K). photon_flux_m2_s: in-band
    photons s^-1 m^-2 at the aperture (``band_nm``). source_id: catalogue id.
    n_hidden_by_spheres: stars in the field behind an occluding sphere.
    n_hidden_by_mask: stars in the field (not behind a sphere) behind the target's mask.
    band_nm: the pass band (nm) of the photon flux.
    """

    x_px: np.ndarray
    y_px: np.ndarray
    v_mag: np.ndarray
    temperature_k: np.ndarray
    photon_flux_m2_s: np.ndarray
    source_id: np.ndarray
    n_hidden_by_spheres: int
    n_hidden_by_mask: int
    band_nm: tuple[float, float]

    def __len__(self) -> int:
        return int(self.x_px.shape[0])

    def labels(self) -> dict:
        """The frame's star labels, JSON-ready: every star drawn (centre on the image or
        within the margin around it) with its catalogue id, pixel position and V magnitude,
        and how many stars in the field the target and the Earth or Moon hide."""
        return {
            "star_count": len(self),
            "stars_hidden_by_target": int(self.n_hidden_by_mask),
            "stars_hidden_by_earth_or_moon": int(self.n_hidden_by_spheres),
            "stars": [
                {
                    "source_id": int(sid),
                    "x_px": float(x),
                    "y_px": float(y),
                    "v_mag": round(float(v), 3),
                }
                for sid, x, y, v in zip(
                    self.source_id, self.x_px, self.y_px, self.v_mag, strict=True
                )
            ],
        }


def _check_rotation(R: object) -> np.ndarray:
    m = np.asarray(R, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise SatsightError(
            f"R_cam_from_gcrs must be a finite (3, 3) rotation matrix; got shape {m.shape}"
        )
    if np.max(np.abs(m @ m.T - np.eye(3))) > 1e-6 or np.linalg.det(m) < 0:
        raise SatsightError(
            "R_cam_from_gcrs must be a proper rotation (orthonormal, det +1); it is not. "
            "Build it from a unit quaternion, x_cam = R_cam_from_gcrs @ x_gcrs"
        )
    return m


def _check_spheres(spheres: Sequence) -> list[tuple[np.ndarray, float]]:
    out = []
    for k, item in enumerate(spheres):
        try:
            centre, radius = item
            c = np.asarray(centre, dtype=np.float64)
            r = float(radius)
        except (TypeError, ValueError):
            c, r = np.zeros(0), math.nan
        if c.shape != (3,) or not np.all(np.isfinite(c)) or not (r > 0 and math.isfinite(r)):
            raise SatsightError(
                f"occluding_spheres_cam[{k}] must be (center_cam_m (3,), radius_m > 0) with "
                f"finite values; got {item!r}"
            )
        out.append((c, r))
    return out


def _hidden_by_spheres(d_cam: np.ndarray, spheres: list[tuple[np.ndarray, float]]) -> np.ndarray:
    """(N,) True where the ray t d (t > 0) from the camera origin meets a sphere."""
    hidden = np.zeros(d_cam.shape[0], dtype=bool)
    for c, r in spheres:
        along = d_cam @ c
        miss2 = float(c @ c) - along**2  # squared distance from the centre to the ray's line
        inside = float(c @ c) <= r * r
        hidden |= inside | ((along > 0) & (miss2 < r * r))
    return hidden


def stars_in_view(
    catalog: StarCatalog,
    R_cam_from_gcrs: np.ndarray,
    camera: PinholeCamera,
    epoch_utc: str,
    camera_velocity_gcrs_m_s: np.ndarray,
    occluding_spheres_cam: Sequence[tuple[np.ndarray, float]] = (),
    object_mask: np.ndarray | None = None,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    margin_px: float = DEFAULT_MARGIN_PX,
) -> StarsInView:
    """The catalogue stars a camera sees at an epoch, with pixel positions and photon flux.

    R_cam_from_gcrs: (3, 3) rotation, x_cam = R @ x_gcrs (camera frame OpenCV: +z boresight).
    camera: the pinhole model (its K). epoch_utc: UTC ISO-8601 time of the exposure.
    camera_velocity_gcrs_m_s: (3,) the camera's geocentric velocity (m/s); the observer's
    barycentric velocity is the Earth's (DE421) plus this (Newtonian sum, error ~v^2/c^2).
    occluding_spheres_cam: (center_cam_m (3,), radius_m) in the camera frame: the Earth
    (with an atmosphere margin of the caller's choice), the Moon. A star whose ray from the
    camera meets a sphere is hidden; a camera inside a sphere sees no star at all.
    object_mask: (H, W) bool image of the rendered target; a star whose nearest pixel is True
    is hidden (a point source behind an opaque body). band_nm: pass band (nm) of the flux.
    margin_px: stars whose centre lies up to this far outside the image are kept.

    Apparent direction: u' = aberrate(directions_icrs(catalog, epoch), v_earth + v_cam);
    kept when d_cam = R u' has z > 0 and (K d / d_z) falls within the image grown by
    margin_px on each side: -0.5 - margin <= x <= W - 0.5 + margin (same for y).
    """
    R = _check_rotation(R_cam_from_gcrs)
    v_cam = np.asarray(camera_velocity_gcrs_m_s, dtype=np.float64)
    if v_cam.shape != (3,) or not np.all(np.isfinite(v_cam)):
        raise SatsightError(
            f"camera_velocity_gcrs_m_s must be a finite 3-vector in m/s; got {v_cam!r}"
        )
    band = check_band_nm(band_nm)
    if not (math.isfinite(float(margin_px)) and margin_px >= 0):
        raise SatsightError(f"margin_px must be a finite number of pixels >= 0; got {margin_px}")
    spheres = _check_spheres(occluding_spheres_cam)
    h, w = camera.height_px, camera.width_px
    if object_mask is not None:
        mask = np.asarray(object_mask)
        if mask.shape != (h, w) or mask.dtype != np.bool_:
            raise SatsightError(
                f"object_mask must be a bool image of the camera's shape ({h}, {w}); got "
                f"{mask.dtype} {mask.shape}"
            )
    epoch = parse_epoch_utc(epoch_utc)

    # Cheap pre-selection on the unaberrated J2016 directions (aberration + 10 yr of proper
    # motion move a star by well under 1 deg).
    boresight_gcrs = R[2]
    half_diag = 0.5 * camera.fov_diagonal_rad + margin_px * camera.ifov_rad + math.radians(1.0)
    x_icrs, y_icrs, z_icrs = catalog.unit_xyz_icrs
    cos_sep = x_icrs * boresight_gcrs[0] + y_icrs * boresight_gcrs[1] + z_icrs * boresight_gcrs[2]
    near = np.flatnonzero(cos_sep > math.cos(min(half_diag, math.pi)))
    sub = _subset(catalog, near)

    v_obs = earth_velocity_bcrs_m_s(epoch) + v_cam
    u = aberrate(directions_icrs(sub, julian_year_tt(epoch)), v_obs)
    d_cam = u @ R.T
    front = d_cam[:, 2] > 0
    z = np.where(front, d_cam[:, 2], 1.0)
    x = camera.focal_length_px * d_cam[:, 0] / z + camera.cx_px
    y = camera.focal_length_px * d_cam[:, 1] / z + camera.cy_px
    m = float(margin_px)
    inside = front & (x >= -0.5 - m) & (x <= w - 0.5 + m) & (y >= -0.5 - m) & (y <= h - 0.5 + m)
    idx = np.flatnonzero(inside)

    by_sphere = _hidden_by_spheres(d_cam[idx], spheres)
    by_mask = np.zeros(idx.size, dtype=bool)
    if object_mask is not None:
        col, row = np.rint(x[idx]).astype(np.int64), np.rint(y[idx]).astype(np.int64)
        on = (col >= 0) & (col < w) & (row >= 0) & (row < h) & ~by_sphere
        by_mask[on] = mask[row[on], col[on]]
    keep = idx[~by_sphere & ~by_mask]
    flux = star_photon_flux_m2_s(sub.v_mag[keep], sub.temperature_k[keep], band)
    return StarsInView(
        x_px=x[keep],
        y_px=y[keep],
        v_mag=sub.v_mag[keep].copy(),
        temperature_k=sub.temperature_k[keep].copy(),
        photon_flux_m2_s=flux,
        source_id=sub.source_id[keep].copy(),
        n_hidden_by_spheres=int(by_sphere.sum()),
        n_hidden_by_mask=int(by_mask.sum()),
        band_nm=band,
    )


def _subset(catalog: StarCatalog, index: np.ndarray) -> StarCatalog:
    """The stars ``index`` of a catalogue, as a catalogue."""
    return catalog.take(index)


# --- photons on the focal plane --------------------------------------------------------------


def collecting_area_m2(optics: Optics) -> float:
    """Unobscured entrance-pupil area pi D^2 / 4 (1 - eps^2), m^2."""
    return math.pi * optics.aperture_diameter_m**2 / 4.0 * (1.0 - optics.obscuration_ratio**2)


def star_photon_counts(
    photon_flux_m2_s: np.ndarray, optics: Optics, exposure_time_s: float
) -> np.ndarray:
    """(M,) mean photons per star reaching the detector: flux x area x tau x t."""
    t = check_exposure_time_s(exposure_time_s)
    flux = np.asarray(photon_flux_m2_s, dtype=np.float64)
    return flux * (collecting_area_m2(optics) * optics.transmission * t)


def check_exposure_time_s(exposure_time_s: float) -> float:
    try:
        t = float(exposure_time_s)
    except (TypeError, ValueError):
        t = math.nan
    if not (math.isfinite(t) and t >= 0.0):
        raise SatsightError(
            f"exposure_time_s must be a finite number of seconds >= 0; got {exposure_time_s!r}"
        )
    return t
