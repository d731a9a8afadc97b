"""Physical constants and the project's defaults, each defined once, with its source.

SI units throughout; every module that needs one of these imports it from here.
"""

from __future__ import annotations

import math

# --- Fundamental constants (exact in the SI since its 2019 revision: BIPM, "The
# International System of Units", 9th ed., 2019, Table 1; the values scipy.constants
# holds, written out so that importing them does not load scipy) ---

#: Planck constant h, J s.
PLANCK_J_S: float = 6.626_070_15e-34
#: Speed of light in vacuum c, m s^-1.
SPEED_OF_LIGHT_M_S: float = 299_792_458.0
#: Boltzmann constant k, J K^-1.
BOLTZMANN_J_K: float = 1.380_649e-23
#: Stefan-Boltzmann constant sigma = 2 pi^5 k^4 / (15 h^3 c^2), W m^-2 K^-4 (exact from
#: the three above; 5.670374419e-8 to CODATA 2018's ten digits).
STEFAN_BOLTZMANN_W_M2_K4: float = (
    2.0 * math.pi**5 * BOLTZMANN_J_K**4 / (15.0 * PLANCK_J_S**3 * SPEED_OF_LIGHT_M_S**2)
)

# --- Astronomy ---

#: The astronomical unit, m (IAU 2012 Resolution B2, exact by definition).
AU_M = 149_597_870_700.0

# --- The Earth ---

#: Mean radius R1 of the Earth, m: IUGG / Geodetic Reference System 1980 (Moritz,
#: "Geodetic Reference System 1980", Bulletin Geodesique 54, 395-405, 1980).
EARTH_MEAN_RADIUS_M = 6_371_008.8
#: Equatorial radius (semi-major axis a) of the WGS-84 ellipsoid, m: a defining parameter
#: (NIMA TR8350.2, 3rd ed., Table 3.1; Vallado, 4th ed., Appendix D). EGM96 uses the same
#: reference radius.
WGS84_SEMI_MAJOR_AXIS_M = 6_378_137.0
#: Inverse flattening 1/f of the WGS-84 ellipsoid (NIMA TR8350.2, Table 3.1).
WGS84_INVERSE_FLATTENING = 298.257223563
#: Semi-minor axis b = a (1 - f) of the WGS-84 ellipsoid, m.
WGS84_SEMI_MINOR_AXIS_M = WGS84_SEMI_MAJOR_AXIS_M * (1.0 - 1.0 / WGS84_INVERSE_FLATTENING)
#: The Earth's equatorial radius, m: WGS-84 a, also the reference radius of the EGM96
#: gravity field's zonal harmonics (Lemoine et al., NASA/TP-1998-206861).
EARTH_EQUATORIAL_RADIUS_M = WGS84_SEMI_MAJOR_AXIS_M
#: Earth's Bond albedo, about 0.30 (Stephens et al., "The albedo of Earth", Rev. Geophys.
#: 53, 141-163, 2015: 0.29 from CERES; NASA GSFC Earth Fact Sheet: 0.306). For a
#: Lambertian sphere the Bond (spherical) albedo equals the surface albedo rho.
EARTH_ALBEDO = 0.30

# --- The Moon ---

#: Mean radius of the Moon, m: IAU Working Group on Cartographic Coordinates and
#: Rotational Elements (Archinal et al., Celest. Mech. Dyn. Astron. 109, 101-135, 2011).
MOON_MEAN_RADIUS_M = 1_737_400.0
#: The Moon's albedo, about 0.12 (NASA GSFC Moon Fact Sheet: geometric albedo 0.12, Bond
#: albedo 0.11).
MOON_ALBEDO = 0.12

# --- The camera's band ---

#: The paper's imaging band, nm: the default ``sun.band_nm`` of a scenario, and the band
#: of every in-band quantity (irradiance, reflectance, QE average) unless one is given.
DEFAULT_BAND_NM: tuple[float, float] = (450.0, 900.0)

#: Luminance weights of linear Rec. 709 RGB (ITU-R BT.709-6, item 3.2).
REC709_LUMINANCE_RGB = (0.2126, 0.7152, 0.0722)
