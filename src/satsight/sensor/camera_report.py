"""A camera's figures of merit: sampling, reference exposure and limiting magnitude.

What ``satsight camera`` prints. The reference exposure is the one the default exposure
rule (``mode: auto``) gives a sunlit grey target: a Lambertian surface of albedo 0.3
facing the Sun, seen along its normal, radiance L = rho E_sun / pi (E_sun the in-band
irradiance at 1 AU), filled to the rule's fraction of full well. The detector's quantum
efficiency is the chain's (``SensorChain.quantum_efficiency``) for the target and the star's
own (its black body) for the limiting magnitudes.
"""

from __future__ import annotations

import math

from satsight.lighting.solar_spectrum import band_irradiance_w_m2
from satsight.sensor.chain import SensorChain
from satsight.sensor.exposure import exposure_for_fill
from satsight.sensor.limiting_magnitude import limiting_magnitude_details
from satsight.sensor.optics import focal_plane_irradiance_w_m2

#: Albedo of the reference grey target (typical of a satellite's mean albedo; assumption).
REFERENCE_ALBEDO = 0.3
#: Exposures of the limiting-magnitude table, s.
EXPOSURES_S = (1e-3, 1e-2, 1e-1, 1.0)
#: The detection threshold of the limiting magnitude.
SNR_LIMIT = 5.0


def reference_exposure_s(sensor: SensorChain, albedo: float = REFERENCE_ALBEDO) -> float:
    """Exposure (s) the auto rule gives a sunlit Lambertian target of ``albedo`` at 1 AU."""
    sun_w_m2 = band_irradiance_w_m2(sensor.band_nm, sensor.spectrum)
    radiance = albedo * sun_w_m2 / math.pi
    focal = float(focal_plane_irradiance_w_m2(radiance, sensor.optics))
    t = exposure_for_fill(
        focal,
        sensor.detector,
        sensor.band_nm,
        sensor.exposure.fill_fraction,
        sensor.effective_wavelength_m,
        quantum_efficiency=sensor.quantum_efficiency,
    )
    if sensor.exposure.mode == "fixed":
        return sensor.exposure.time_s
    return min(max(t, sensor.exposure.min_time_s), sensor.exposure.max_time_s)


def camera_report(sensor: SensorChain) -> dict:
    """The camera's optics, sampling and limiting magnitudes (V at SNR 5), JSON-ready."""
    optics, camera, detector = sensor.optics, sensor.camera, sensor.detector
    lam = sensor.effective_wavelength_m
    airy_radius_m = 1.21967 * lam * optics.f_number  # first dark ring, clear pupil
    t_ref = reference_exposure_s(sensor)

    def limit(t: float) -> dict:
        details = limiting_magnitude_details(
            optics, detector, t, sensor.band_nm, SNR_LIMIT, temperature_k=5772.0
        )
        return {
            "exposure_time_s": t,
            "v_mag": details.v_mag,
            "photons": details.photons,
            "aperture_px": details.n_pixels,
            "star_quantum_efficiency": details.quantum_efficiency,
        }

    return {
        "focal_length_m": optics.focal_length_m,
        "aperture_diameter_m": optics.aperture_diameter_m,
        "f_number": optics.f_number,
        "transmission": optics.transmission,
        "ifov_urad": camera.ifov_rad * 1e6,
        "fov_deg": [math.degrees(camera.fov_x_rad), math.degrees(camera.fov_y_rad)],
        "effective_wavelength_nm": lam * 1e9,
        "quantum_efficiency": sensor.quantum_efficiency,
        "quantum_efficiency_source": sensor.quantum_efficiency_source,
        "airy_radius_px": airy_radius_m / camera.pixel_pitch_m,
        "nyquist_over_cutoff": (1 / (2 * camera.pixel_pitch_m)) / (1 / (lam * optics.f_number)),
        "reference_exposure": {
            "description": f"sunlit Lambertian target, albedo {REFERENCE_ALBEDO}, at 1 AU, "
            f"filled to {sensor.exposure.fill_fraction:g} of full well",
            **limit(t_ref),
        },
        "limiting_magnitude_snr5": [limit(t) for t in EXPOSURES_S],
    }
