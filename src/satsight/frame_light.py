"""The light at the target in one frame of a plan: the Sun (its in-band irradiance at the
frame's distance), the Earth and the Moon as bodies and as the SH light field, in the
target's body frame."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from satsight.config.scenario import Scenario
from satsight.constants import EARTH_ALBEDO, MOON_ALBEDO, MOON_MEAN_RADIUS_M
from satsight.ephemeris.earth_orientation import R_itrs_from_gcrs
from satsight.ephemeris.time import parse_epoch_utc
from satsight.frames.rigid import RigidTransform
from satsight.lighting.bodies import environment_light_field
from satsight.lighting.light_field import LightField
from satsight.lighting.scene_bodies import earth_body, moon_body
from satsight.lighting.solar_spectrum import irradiance_at_distance_w_m2
from satsight.poses.track import PoseTrack


def sun_irradiance_w_m2(scenario: Scenario, track: PoseTrack, index: int) -> float:
    """The Sun's in-band irradiance (W m^-2) at the target in plan frame ``index``, before
    the Earth's shadow: the scenario's ``sun`` value for hand-placed views; on an orbit, its
    value at 1 AU scaled to the frame's Sun distance (inverse square)."""
    if scenario.sampler is None:
        return scenario.sun.in_band_irradiance_w_m2
    at_1_au = scenario.sun.model_copy(update={"distance_au": 1.0}).in_band_irradiance_w_m2
    return irradiance_at_distance_w_m2(at_1_au, track.sun_distance_m[index])


# A frame's light is computed from its inputs in the body frame (the Sun's direction, the
# Earth's and the Moon's centres, the Earth's orientation) put on a grid of 2^-32 of each
# one's size (the power of two above 1 for directions and rotations, above the body's
# distance for its centre): about 2e-10 relative; 0.05 mas for the Sun's direction, 2 mm
# for the Earth's centre from low orbit, 16 mm from geostationary orbit. Frames that share
# the target's state (an RSSF plan's frames at one epoch) reach their body-frame inputs
# through their own camera rotations, which differ in the last bits (1e-15 relative,
# measured); on the grid they are equal, bit for bit, so that such frames share one light
# field (``FrameEngine`` keeps the last few), but where a value falls within that of a
# step's edge (about 1 value in 10^5, 1 frame in 10^4), which costs one more light field.
# A frame's light stays a function of its own plan entry alone: resumed and sharded
# datasets get the same bytes. (The step is set by the size, not by the vector's norm: a
# unit vector's norm falls on either side of 1 by an ulp, which would halve the step from
# frame to frame.)
_GRID_BITS = 32


def _on_grid(values: np.ndarray, size: float = 1.0) -> tuple[float, ...]:
    """``values`` (flattened) rounded to multiples of 2^-32 of the power of two above
    ``size`` (a power of two: the rounding is exact)."""
    _, exponent = math.frexp(float(size))
    grid = math.ldexp(1.0, exponent - _GRID_BITS)
    values = np.asarray(values, dtype=np.float64).ravel()
    # + 0.0 makes -0.0 +0.0: the two compare (and hash) equal, so their bits must be too.
    return tuple((np.round(values / grid) * grid + 0.0).tolist())


@dataclasses.dataclass(frozen=True)
class LightInputs:
    """What a frame's light depends on beyond its scenario, in the body frame, on the grid
    above (hashable: equal inputs give equal light).

    sun_direction_body: from the target towards the Sun. irradiance_w_m2: the Sun's in-band
    irradiance that lights the Earth and the Moon; at_target_w_m2: what reaches the target.
    earth_center_body_m, moon_center_body_m: from the target to the bodies' centres (None
    without an ``earth`` / ``moon`` section). R_body_from_earth_fixed: the Earth's fixed
    frame's orientation, row-major (None without an ``earth`` section).
    """

    sun_direction_body: tuple[float, ...]
    irradiance_w_m2: float
    at_target_w_m2: float
    earth_center_body_m: tuple[float, ...] | None
    R_body_from_earth_fixed: tuple[float, ...] | None
    moon_center_body_m: tuple[float, ...] | None


def frame_light_inputs(
    scenario: Scenario,
    track: PoseTrack,
    index: int,
    cam_from_body: RigidTransform | None = None,
    sun_direction_cam: np.ndarray | None = None,
    irradiance_scale: float = 1.0,
    earth_direction_cam: np.ndarray | None = None,
) -> LightInputs:
    """The inputs of frame ``index``'s light (``frame_light``).

    A randomised frame (``satsight.frame_variation``) gives the target's pose in the plan's
    camera frame (``cam_from_body``, turned by its attitude jitter), the Sun's direction in
    that frame, a factor on the Sun's irradiance and the Earth's direction in that frame
    (moved behind the target); defaults: the plan's.
    """
    cam_from_body = track.cam_from_body(index) if cam_from_body is None else cam_from_body
    R_body_from_cam = cam_from_body.R_a_from_b.T
    irradiance = sun_irradiance_w_m2(scenario, track, index) * irradiance_scale
    if sun_direction_cam is None:
        sun_direction_cam = track.sun_from_target_cam[index]
    if earth_direction_cam is None:
        earth_direction_cam = track.earth_from_target_cam[index]

    def centre(direction_cam: np.ndarray, distance_m: float) -> tuple[float, ...]:
        return _on_grid(R_body_from_cam @ (direction_cam * distance_m), distance_m)

    earth = scenario.earth is not None
    return LightInputs(
        sun_direction_body=_on_grid(R_body_from_cam @ sun_direction_cam),
        irradiance_w_m2=float(irradiance),
        at_target_w_m2=float(irradiance * float(track.sunlit_fraction[index])),
        earth_center_body_m=centre(earth_direction_cam, track.earth_distance_m[index])
        if earth
        else None,
        R_body_from_earth_fixed=_on_grid(R_body_from_cam @ _R_cam_from_earth_fixed(track, index))
        if earth
        else None,
        moon_center_body_m=centre(track.moon_from_target_cam[index], track.moon_distance_m[index])
        if scenario.moon is not None
        else None,
    )


def light_from_inputs(scenario: Scenario, inputs: LightInputs) -> LightField:
    """The light at the target, body frame, from a frame's ``LightInputs``: the Sun, and the
    Earth and the Moon of the scenario's ``earth`` / ``moon`` sections as bodies and as the
    SH light field (``frame_light``)."""
    earth, moon = scenario.earth, scenario.moon
    sun_body = np.array(inputs.sun_direction_body)
    irradiance = inputs.irradiance_w_m2
    earth_center = None if earth is None else np.array(inputs.earth_center_body_m)
    moon_center = None if moon is None else np.array(inputs.moon_center_body_m)
    bodies = []
    if earth is not None:
        bodies.append(
            earth_body(
                earth_center,
                np.array(inputs.R_body_from_earth_fixed).reshape(3, 3),
                earth.albedo,
                sun_body,
                irradiance,
                albedo_map=earth.albedo_map(),
                shape=earth.shape,
            )
        )
    # The SH field (environment: sh, unshadowed) projects the same Earth the renderer
    # traces: its shape, orientation and albedo map.
    light = environment_light_field(
        sun_body,
        irradiance,
        earth_center_from_target_m=earth_center,
        earth_albedo=EARTH_ALBEDO if earth is None else earth.albedo,
        moon_center_from_target_m=moon_center,
        moon_albedo=MOON_ALBEDO if moon is None else moon.albedo,
        l_max=scenario.render.sh_order,
        sun_irradiance_at_target_w_m2=inputs.at_target_w_m2,
        earth=bodies[0] if bodies else None,
    )
    if moon is not None:
        bodies.append(moon_body(moon_center, MOON_MEAN_RADIUS_M, moon.albedo, sun_body, irradiance))
    return dataclasses.replace(light, bodies=tuple(bodies))


def frame_light(scenario: Scenario, track: PoseTrack, index: int) -> LightField:
    """The light at the target in frame ``index`` of the plan, in the body frame.

    The Sun's in-band irradiance is the scenario's value at 1 AU scaled by the inverse square
    of the frame's Sun distance; the Earth and the Moon are lit by all of it, the target by
    its ``sunlit_fraction`` (partly or wholly in the Earth's shadow). Earthshine and moonshine
    are included when the scenario has ``earth`` / ``moon`` sections: as SH coefficients and
    as bodies in the scene (``SceneBody``; the Earth's fixed frame is the ITRS at the frame's
    epoch, or the target's body frame when the scenario has no epoch).

    The same as ``light_from_inputs(scenario, frame_light_inputs(scenario, track, index))``;
    a randomised frame gives ``frame_light_inputs`` its own pose, Sun and Earth.
    """
    return light_from_inputs(scenario, frame_light_inputs(scenario, track, index))


def _R_cam_from_earth_fixed(track: PoseTrack, index: int) -> np.ndarray:
    """Rotation from the Earth's fixed frame (ITRS at the frame's epoch, skyfield's
    precession-nutation and Earth rotation) to the camera frame; without an inertial
    attitude (views given in the body frame) the target's body frame stands in for it."""
    if not (track.has_sky and track.epoch_utc[index]):
        return track.cam_from_body(index).R_a_from_b
    R_itrs_from_gcrs_now = R_itrs_from_gcrs(parse_epoch_utc(track.epoch_utc[index]))[0]
    return track.R_cam_from_gcrs(index) @ R_itrs_from_gcrs_now.T
