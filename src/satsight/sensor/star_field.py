"""The star field behind the target: which stars a camera sees, where, and how bright.

Chain, for one frame:

1. :func:`stars_in_view`: catalogue directions at the epoch (proper motion,
   :func:`satsight.sensor.star_catalog.directions_icrs`), aberrated for the camera's
   barycentric velocity (the Earth's, from DE421, plus the camera's geocentric one), rotated
   into the camera frame and projected with the pinhole model; stars behind occluding
   spheres (the Earth with an atmosphere margin, the Moon) or behind the rendered target
   (``object_mask``) are removed; in-band photon flux from V and temperature.
2. :func:`star_photons_image`: each star's photons spread over the pixels by the
   pixel-integrated, band-averaged PSF of the optics at its exact sub-pixel position.
3. :func:`limiting_magnitude`: the faintest V that reaches a given SNR with the detector.

Frames: GCRS and ICRS share their axes (no rotation between them); the BCRS -> GCRS
relativistic scale change (~1e-8) is irrelevant for directions. Annual parallax and the
gravitational light deflection by the Sun (< ~16 mas beyond 30 deg from the Sun) are not
applied (nor is the stars' parallax, see :mod:`satsight.sensor.star_catalog`); with that,
the pixel positions agree with astropy's space motion + GCRS transformation to 0.008 px at
f = 3 m and 0.002 px at f = 0.7 m with 15 um pixels (test_star_field).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.constants as const
from skyfield.timelib import Time

from satsight.camera.pinhole import PinholeCamera
from satsight.ephemeris.sun_moon import ephemeris
from satsight.ephemeris.time import parse_epoch_utc
from satsight.errors import SatsightError
from satsight.lighting.solar_spectrum import check_band_nm
from satsight.sensor.detector import DetectorParameters
from satsight.sensor.mtf import band_wavelengths_m, defocus_mtf, diffraction_mtf
from satsight.sensor.optics import Optics
from satsight.sensor.star_catalog import (
    SOLAR_TEMPERATURE_K,
    StarCatalog,
    aberrate,
    directions_icrs,
    star_photon_flux_m2_s,
)

DEFAULT_BAND_NM: tuple[float, float] = (450.0, 900.0)
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
    cd = np.cos(catalog.dec_rad)
    cos_sep = (
        cd * np.cos(catalog.ra_rad) * boresight_gcrs[0]
        + cd * np.sin(catalog.ra_rad) * boresight_gcrs[1]
        + np.sin(catalog.dec_rad) * boresight_gcrs[2]
    )
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
    t = _check_exposure(exposure_time_s)
    flux = np.asarray(photon_flux_m2_s, dtype=np.float64)
    return flux * (collecting_area_m2(optics) * optics.transmission * t)


def _check_exposure(exposure_time_s: float) -> float:
    try:
        t = float(exposure_time_s)
    except (TypeError, ValueError):
        t = math.nan
    if not (math.isfinite(t) and t >= 0.0):
        raise SatsightError(
            f"exposure_time_s must be a finite number of seconds >= 0; got {exposure_time_s!r}"
        )
    return t


def _oversampling(optics: Optics, pixel_pitch_m: float, band_nm: tuple[float, float]) -> int:
    """Odd s with s / (2 p) above the diffraction cut-off 1 / (lambda_min N)."""
    cutoff = 1.0 / (band_nm[0] * 1e-9 * optics.f_number)
    return 2 * math.ceil(cutoff * pixel_pitch_m) + 1


def psf_temperature_k(temperature_k: np.ndarray) -> np.ndarray:
    """Temperature (K) whose photon spectrum weights a star's PSF: the star's, rounded to a
    geometric grid through 5772 K with ratio 1.25 (so PSFs are computed once per grid value
    and cached; the PSF changes by < 0.3 % of its peak across one grid step)."""
    t = np.asarray(temperature_k, dtype=np.float64)
    step = math.log(PSF_TEMPERATURE_RATIO)
    return SOLAR_TEMPERATURE_K * np.exp(np.rint(np.log(t / SOLAR_TEMPERATURE_K) / step) * step)


@functools.lru_cache(maxsize=64)
def _weighted_otf(
    optics: Optics,
    pixel_pitch_m: float,
    band_nm: tuple[float, float],
    size: int,
    temperature_k: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """System OTF on the fine frequency grid of a size x size stamp, for one spectrum.

    Returns (otf (F, F), rows f_y and columns f_x in FFT order, freq (F,) cycles/m, s) with
    F = size * s: the diffraction OTF averaged over 16 sub-band centre wavelengths weighted
    by the photon spectrum lambda B_lambda(T), times the pixel sinc(p f_x) sinc(p f_y), the
    jitter MTF exp(-2 pi^2 sigma^2 |f|^2) and, with defocus, the signed geometric defocus OTF
    2 J1(pi d |f|) / (pi d |f|) (:func:`satsight.sensor.mtf.defocus_mtf`). The product
    still vanishes beyond the diffraction cut-off, so the grid cuts no frequency.
    """
    s = _oversampling(optics, pixel_pitch_m, band_nm)
    f = np.fft.fftfreq(size * s, d=pixel_pitch_m / s)
    rho = np.hypot(f[:, None], f[None, :])
    lam = band_wavelengths_m(band_nm, N_PSF_WAVELENGTHS)
    x = const.h * const.c / (lam * const.k * temperature_k)
    weights = lam**-4 / np.expm1(x)
    weights /= weights.sum()
    otf = np.zeros_like(rho)
    for lk, wk in zip(lam, weights, strict=True):
        otf += wk * diffraction_mtf(rho, lk, optics.f_number, optics.obscuration_ratio)
    pix = np.sinc(pixel_pitch_m * f)
    otf *= pix[:, None] * pix[None, :]
    otf *= np.exp(-2.0 * math.pi**2 * optics.jitter_rms_m**2 * rho**2)
    if optics.defocus_blur_diameter_m > 0.0:
        otf *= defocus_mtf(rho, optics.defocus_blur_diameter_m)
    otf.setflags(write=False)
    return otf, f, s


def _fold_and_invert(
    otf: np.ndarray,
    f: np.ndarray,
    s: int,
    size: int,
    dx_px: np.ndarray,
    dy_px: np.ndarray,
    pixel_pitch_m: float,
) -> np.ndarray:
    """(M, size, size) pixel-centre samples of the shifted pixel-integrated PSF."""
    shift = -2j * math.pi * pixel_pitch_m * f
    ex = np.exp(dx_px[:, None] * shift[None, :]).reshape(-1, s, size)
    ey = np.exp(dy_px[:, None] * shift[None, :]).reshape(-1, s, size)
    otf5 = otf.reshape(s, size, s, size)  # [alias y, coarse y, alias x, coarse x]
    half = np.einsum("jakb,mkb->mjab", otf5, ex)
    folded = np.einsum("mjab,mja->mab", half, ey)
    stamps = np.fft.fftshift(np.fft.ifft2(folded).real, axes=(1, 2))
    np.maximum(stamps, 0.0, out=stamps)
    return stamps


def psf_stamps(
    dx_px: np.ndarray,
    dy_px: np.ndarray,
    temperature_k: np.ndarray,
    optics: Optics,
    pixel_pitch_m: float,
    band_nm: tuple[float, float],
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
) -> np.ndarray:
    """(M, S, S) fraction of each star's photons in each pixel, S = 2 R + 1, float64.

    dx_px, dy_px: (M,) offset of the star from the centre pixel of its stamp (px, in
    [-0.5, 0.5]). temperature_k: (M,) the diffraction OTF is averaged over the band's
    sub-band wavelengths weighted by the photon spectrum lambda B_lambda(T) at
    :func:`psf_temperature_k` (flat quantum efficiency).

    Method (exact up to the periodic wrap below): the pixel-integrated PSF sampled at pixel
    centres is the inverse Fourier transform of OTF(f) sinc(p f_x) sinc(p f_y) e^{-2 pi i f.x0}
    (Goodman, Introduction to Fourier Optics, Sec. 6.3; Holst, Ch. 10), OTF = mean
    diffraction OTF x jitter MTF x geometric defocus OTF (signed; 1 without defocus). It is
    evaluated on the frequency grid of an S*s-point stamp with s odd and s / (2 p) above the
    diffraction cut-off (so no frequency is cut),
    multiplied by the sub-pixel phase ramp, folded onto the S x S grid (= sampling at the
    pixel centres, aliases included: the PSF is undersampled) and inverse-FFT'd. Sampling a
    period of S pixels wraps the PSF wings beyond the stamp back into it (at the opposite
    edge): each stamp sums to exactly 1 (the pixel sinc vanishes at every alias of f = 0), so
    a star's photons are conserved; the price is that the outer stamp pixels also hold the
    wings' aliases, about 2 lambda N / (pi^2 R p) of the photons in all (~1 % for R = 8 px at
    f/10 with 15 um pixels), and a centroid bias below ~0.01 px from the wrap.
    """
    R = int(stamp_radius_px)
    if R != stamp_radius_px or R < 1:
        raise SatsightError(f"stamp_radius_px must be a whole number >= 1; got {stamp_radius_px}")
    size = 2 * R + 1
    dx = np.atleast_1d(np.asarray(dx_px, dtype=np.float64))
    dy = np.atleast_1d(np.asarray(dy_px, dtype=np.float64))
    t_psf = psf_temperature_k(np.atleast_1d(np.asarray(temperature_k, dtype=np.float64)))
    band = (float(band_nm[0]), float(band_nm[1]))
    stamps = np.empty((dx.size, size, size))
    for t in np.unique(t_psf):
        sel = t_psf == t
        otf, f, s = _weighted_otf(optics, float(pixel_pitch_m), band, size, float(t))
        stamps[sel] = _fold_and_invert(otf, f, s, size, dx[sel], dy[sel], float(pixel_pitch_m))
    return stamps


def star_photons_image(
    stars: StarsInView,
    shape_hw: tuple[int, int],
    optics: Optics,
    pixel_pitch_m: float,
    exposure_time_s: float,
    band_nm: tuple[float, float],
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
    out: np.ndarray | None = None,
    scale: float = 1.0,
) -> np.ndarray:
    """(H, W) float32 mean photons per pixel reaching the detector from the stars.

    With ``out`` ((H, W) float32), the stars' photons times ``scale`` are added into it in
    place and it is returned (e.g. scale = photon energy / (pixel area x t) adds them as
    focal-plane irradiance without a full-frame temporary).

    Each star delivers N = photon_flux_m2_s x pi D^2 / 4 (1 - eps^2) x tau x t photons,
    spread over a (2 R + 1)^2 stamp by :func:`psf_stamps` (pixel-integrated, photon-weighted
    band-averaged PSF at the star's sub-pixel position; a stamp sums to 1, see there).
    Stamp pixels outside the frame are dropped (those photons miss the detector).
    band_nm must be the band of ``stars`` (their photon flux).
    """
    band = check_band_nm(band_nm)
    if tuple(stars.band_nm) != band:
        raise SatsightError(
            f"band_nm {band} differs from the band of the stars' photon flux {stars.band_nm}; "
            "use the same band for stars_in_view and star_photons_image"
        )
    try:
        h, w = (int(v) for v in shape_hw)
    except (TypeError, ValueError):
        h = w = 0
    if h < 1 or w < 1 or tuple(shape_hw) != (h, w):
        raise SatsightError(f"shape_hw must be (H, W) whole numbers >= 1; got {shape_hw!r}")
    pitch = float(pixel_pitch_m)
    if not (math.isfinite(pitch) and pitch > 0):
        raise SatsightError(f"pixel_pitch_m must be > 0 m; got {pixel_pitch_m!r}")
    counts = star_photon_counts(stars.photon_flux_m2_s, optics, exposure_time_s)
    if out is None:
        image = np.zeros((h, w), dtype=np.float32)
    else:
        image = out
        if image.shape != (h, w) or image.dtype != np.float32:
            raise SatsightError(
                f"out must be a float32 (H, W) = {(h, w)} image; got {image.dtype} {image.shape}"
            )
    if not (math.isfinite(float(scale)) and scale >= 0):
        raise SatsightError(f"scale must be a finite number >= 0; got {scale!r}")
    counts = counts * float(scale)
    R = int(stamp_radius_px)
    cx = np.rint(stars.x_px).astype(np.int64)
    cy = np.rint(stars.y_px).astype(np.int64)
    touch = (cx + R >= 0) & (cx - R < w) & (cy + R >= 0) & (cy - R < h) & (counts > 0)
    k = np.flatnonzero(touch)
    if k.size == 0:
        return image
    stamps = psf_stamps(
        stars.x_px[k] - cx[k],
        stars.y_px[k] - cy[k],
        stars.temperature_k[k],
        optics,
        pitch,
        band,
        R,
    )
    for n, j in enumerate(k):
        y0, x0 = cy[j] - R, cx[j] - R
        ya, xa = max(y0, 0), max(x0, 0)
        yb, xb = min(y0 + 2 * R + 1, h), min(x0 + 2 * R + 1, w)
        image[ya:yb, xa:xb] += counts[j] * stamps[n, ya - y0 : yb - y0, xa - x0 : xb - x0]
    return image


# --- limiting magnitude ----------------------------------------------------------------------


@dataclass(frozen=True)
class LimitingMagnitude:
    """The faintest star reaching a target SNR, and the aperture that measures it.

    v_mag: its V magnitude. photons: its mean photons reaching the detector.
    signal_e: mean photo-electrons inside the aperture. n_pixels: aperture size (px).
    aperture: (S, S) bool, the aperture's pixels within a stamp centred on the star.
    fraction: (S, S) float, the star's photon fraction per pixel (the PSF stamp).
    noise_var_per_pixel_e2: read^2 + dark t + g^2 / 12 (e^2).
    """

    v_mag: float
    photons: float
    signal_e: float
    n_pixels: int
    aperture: np.ndarray
    fraction: np.ndarray
    noise_var_per_pixel_e2: float


def limiting_magnitude_details(
    optics: Optics,
    detector_params: DetectorParameters,
    exposure_time_s: float,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    snr: float = 5.0,
    temperature_k: float = 5772.0,
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
) -> LimitingMagnitude:
    """The V magnitude at which a star centred on a pixel reaches ``snr``; see
    :func:`limiting_magnitude` for the model."""
    t = _check_exposure(exposure_time_s)
    if t <= 0:
        raise SatsightError(f"exposure_time_s must be > 0 s for a limiting magnitude; got {t}")
    if not (math.isfinite(float(snr)) and snr > 0):
        raise SatsightError(f"snr must be a positive number; got {snr!r}")
    band = check_band_nm(band_nm)
    p = detector_params
    frac = psf_stamps(
        np.zeros(1),
        np.zeros(1),
        np.array([float(temperature_k)]),
        optics,
        p.pixel_pitch_m,
        band,
        stamp_radius_px,
    )[0]
    order = np.argsort(frac, axis=None)[::-1]
    enclosed = np.cumsum(frac.ravel()[order])
    n = np.arange(1, enclosed.size + 1)
    var_px = p.read_noise_e**2 + p.dark_current_e_per_s * t + p.conversion_gain_e_per_dn**2 / 12
    s2 = float(snr) ** 2
    signal = 0.5 * (s2 + np.sqrt(s2 * s2 + 4.0 * s2 * n * var_px))  # x^2 = S^2 (x + n var)
    photons = signal / (p.quantum_efficiency * enclosed)
    best = int(np.argmin(photons))
    aperture = np.zeros(frac.size, dtype=bool)
    aperture[order[: best + 1]] = True
    flux = photons[best] / (collecting_area_m2(optics) * optics.transmission * t)
    flux0 = star_photon_flux_m2_s(np.zeros(1), np.array([float(temperature_k)]), band)[0]
    return LimitingMagnitude(
        v_mag=float(-2.5 * math.log10(flux / flux0)),
        photons=float(photons[best]),
        signal_e=float(signal[best]),
        n_pixels=best + 1,
        aperture=aperture.reshape(frac.shape),
        fraction=frac,
        noise_var_per_pixel_e2=float(var_px),
    )


def limiting_magnitude(
    optics: Optics,
    detector_params: DetectorParameters,
    exposure_time_s: float,
    band_nm: tuple[float, float] = DEFAULT_BAND_NM,
    snr: float = 5.0,
    temperature_k: float = 5772.0,
    stamp_radius_px: int = DEFAULT_STAMP_RADIUS_PX,
) -> float:
    """Faintest V magnitude a star (blackbody at ``temperature_k``) is detected at ``snr``.

    Aperture photometry over the n pixels that maximise the SNR (the n brightest pixels of
    the star's pixel-integrated PSF, star centred on a pixel; the best case), with the CCD
    equation (Howell, Handbook of CCD Astronomy, 2nd ed., Eq. 4.4; EMVA 1288 R4.0 Sec. 2):
    SNR = x / sqrt(x + n (sigma_read^2 + D t + g^2 / 12)), x = eta F_n N the photo-electrons
    in the aperture, F_n its enclosed fraction, g^2 / 12 the quantisation noise (e^2). For
    each n the quadratic x^2 - S^2 x - S^2 n B = 0 gives x; the smallest N over n wins.
    The sky background is zero (space; stray light ignored), PRNU ignored (< 1 % of a faint
    signal). V follows from N = flux(V) A tau t with :func:`star_photon_flux_m2_s`.
    """
    return limiting_magnitude_details(
        optics, detector_params, exposure_time_s, band_nm, snr, temperature_k, stamp_radius_px
    ).v_mag
