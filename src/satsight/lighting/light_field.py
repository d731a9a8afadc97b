"""The light field at the target (paper Eq. 9-13), in the render frame.

The Sun is a collimated source (a direction and an in-band irradiance). Everything else
that lights the target from a finite solid angle (the sunlit Earth, the Moon, other
bodies) is one environment radiance ``L_env(w)`` expanded in real spherical harmonics
(``satsight.lighting.sh``), one coefficient vector per colour channel.

Frame: the render frame is the target's body frame; ``w`` is the direction *towards* the
light source (from the target), like ``sun_direction_body``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from satsight.errors import SatsightError
from satsight.lighting.scene_bodies import SceneBody

# A direction whose length is within this of 1 is unit already (a normalised vector's
# length is 1 to a few ulp): it is kept as given, so that the Sun of a ``LightField`` and
# its ``sun`` are the same bits.
_UNIT_LENGTH_TOLERANCE = 4 * np.finfo(np.float64).eps


@dataclass(frozen=True)
class SunLight:
    """The Sun as a collimated source (the ``LightField``'s Sun alone: ``LightField.sun``).

    direction_body: (3,) unit vector from the target toward the Sun, body frame (any
    length given; scaled to 1).
    irradiance_w_m2: in-band irradiance on a surface facing the Sun, W m^-2.
    """

    direction_body: np.ndarray
    irradiance_w_m2: float

    def __post_init__(self) -> None:
        d = np.asarray(self.direction_body, dtype=np.float64).reshape(3)
        length = np.linalg.norm(d)
        if abs(length - 1.0) > _UNIT_LENGTH_TOLERANCE:
            d = d / length
        object.__setattr__(self, "direction_body", d)


@dataclass(frozen=True)
class LightField:
    """Light arriving at the target.

    sun_direction_body: (3,) unit vector from the target towards the Sun, body frame.
    sun_irradiance_w_m2: in-band solar irradiance on a surface facing the Sun, W m^-2
    (0 when the target is in the Earth's umbra; reduced in the penumbra).
    sh_radiance_w_m2_sr: (n_coeffs, 3) real SH coefficients, per colour channel, of the
    environment radiance L_env(w) in W m^-2 sr^-1 (the Sun excluded), body frame.
    ``n_coeffs = (l_max + 1)^2``, index ``l (l + 1) + m``.
    bodies: the Earth and the Moon as bodies in the scene (``SceneBody``), at most one of
    each. The renderer's ``sampled`` environment traces rays to them instead of using the
    SH expansion (which then holds the same light, for the ``sh`` and ``unshadowed``
    modes and for the labels); every mode shows them behind the target.
    """

    sun_direction_body: np.ndarray
    sun_irradiance_w_m2: float
    sh_radiance_w_m2_sr: np.ndarray
    bodies: tuple[SceneBody, ...] = ()

    def __post_init__(self) -> None:
        d = np.asarray(self.sun_direction_body, dtype=np.float64).reshape(3)
        norm = np.linalg.norm(d)
        if not np.isfinite(norm) or norm == 0.0:
            raise SatsightError(f"sun direction must be a non-zero vector, got {d}")
        object.__setattr__(self, "sun_direction_body", d / norm)
        if not (self.sun_irradiance_w_m2 >= 0.0 and np.isfinite(self.sun_irradiance_w_m2)):
            raise SatsightError(
                f"sun irradiance must be finite and >= 0 W m^-2, got {self.sun_irradiance_w_m2}"
            )
        c = np.asarray(self.sh_radiance_w_m2_sr, dtype=np.float64)
        if c.ndim == 1:
            c = c[:, None].repeat(3, axis=1)
        l_max = round(np.sqrt(c.shape[0])) - 1
        if c.ndim != 2 or c.shape[1] != 3 or (l_max + 1) ** 2 != c.shape[0]:
            raise SatsightError(
                "sh_radiance_w_m2_sr must have shape ((l_max + 1)^2, 3), got "
                f"{np.shape(self.sh_radiance_w_m2_sr)}"
            )
        object.__setattr__(self, "sh_radiance_w_m2_sr", c)
        bodies = tuple(self.bodies)
        names = [b.name for b in bodies]
        if len(set(names)) != len(names) or not all(isinstance(b, SceneBody) for b in bodies):
            raise SatsightError(f"bodies must be SceneBody objects, one per name; got {names}")
        object.__setattr__(self, "bodies", bodies)

    @property
    def sun(self) -> SunLight:
        """The Sun alone, as the renderer lights the target with it (same direction bits)."""
        return SunLight(self.sun_direction_body, self.sun_irradiance_w_m2)

    @property
    def l_max(self) -> int:
        """Highest SH degree of the environment expansion."""
        return round(np.sqrt(self.sh_radiance_w_m2_sr.shape[0])) - 1

    @classmethod
    def sun_only(
        cls, sun_direction_body: np.ndarray, sun_irradiance_w_m2: float, l_max: int = 4
    ) -> LightField:
        """A light field with the Sun and a black environment."""
        return cls(sun_direction_body, sun_irradiance_w_m2, np.zeros(((l_max + 1) ** 2, 3)))
