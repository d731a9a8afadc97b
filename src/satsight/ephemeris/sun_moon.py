"""Where the Sun and the Moon are, seen from the Earth's centre, from JPL DE421 (offline).

Positions are geocentric vectors in **GCRS** (the Geocentric Celestial Reference System:
origin at the Earth's centre of mass, axes of the ICRS), in metres, shape (N, 3), float64.
They come from the JPL planetary and lunar ephemeris DE421 (Folkner, Williams & Boggs, "The
Planetary and Lunar Ephemeris DE 421", IPN Progress Report 42-178, 2009), evaluated by
skyfield on TDB. The kernel ``de421.bsp`` is the copy shipped by the ``skyfield-data``
package; it covers 1899-07-29 to 2053-10-09, and times outside raise ``SatsightError``.
Nothing is ever downloaded.

Which position: **geometric**, for both bodies: the body's barycentric (BCRS) position
minus the Earth's at the *same* instant, ``(eph[body] - eph["earth"]).at(t)``, i.e. where
the body is at t in the Earth-centred frame, with no light-time, aberration or deflection
correction. This is the position that the orbits (:mod:`satsight.ephemeris.orbits`, also
geometric) and shadow and eclipse geometry need, and it is the same definition for the Sun
and the Moon.

Why not light time alone: correcting for light time in the barycentric frame without also
applying aberration (skyfield's ``observe``, an *astrometric* position) moves a body back
along its barycentric path by the light time, so the Earth's own 30 km/s orbital motion
enters. For the Sun (499 s; its barycentric speed is ~12 m/s) this shifts it by 5-8 km,
0.01 arcsec; for the Moon (1.3 s) it shifts it by 35-41 km, 8-21 arcsec from its
geometric position, which is the error this module once had. The *apparent* position
(light time plus annual aberration) differs from the geometric one by the body's motion
relative to the Earth during the light time and the aberration: about 20.5 arcsec for the
Sun (annual aberration; irrelevant for lighting and shadow directions, 1e-4 rad) and
0.7 arcsec (~1.3 km) for the Moon. The BCRS -> GCRS relativistic scale change (about
1e-8) is neglected.

Checked (tests/ephemeris/test_moon_position.py) against astropy reading the same
``de421.bsp`` through jplephem with its own (ERFA) TDB: both bodies agree to 4e-5 m.

J2000 / EME2000: the mean equator and equinox of J2000.0 (the dynamical frame that
"EME2000" denotes in the strict sense) differs from GCRS/ICRS by a constant **frame bias**
of about 23 mas. :func:`eme2000_from_gcrs_matrix` builds it from the IERS values (IERS
Conventions 2010, IERS Technical Note 36, Ch. 5, Eq. 5.21 and Table 5.1, after Chapront et
al. 2002): dα0 = -14.6 mas (ICRS right-ascension origin offset), ξ0 = -16.6170 mas and
η0 = -6.8192 mas (celestial pole offsets), as the exact rotation product
``B = R1(-η0) R2(ξ0) R3(dα0)`` (the same composition as SOFA/ERFA ``bp00``), where
``Ri(θ)`` rotates the coordinate axes by ``θ`` about axis ``i``. Note that many tools
(e.g. SPICE's ``J2000`` frame, most orbit files labelled EME2000) treat J2000 and ICRF as
identical; the bias is 1e-7 rad, about 4 m at geostationary distance.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np
from skyfield.errors import EphemerisRangeError
from skyfield.jpllib import SpiceKernel
from skyfield.timelib import Time

from satsight.constants import AU_M
from satsight.ephemeris.time import skyfield_data_dir, skyfield_loader, timescale
from satsight.errors import SatsightError

EPHEMERIS_FILE = "de421.bsp"

_MAS_TO_RAD = math.pi / (180.0 * 3600.0 * 1000.0)
# Frame-bias angles, mas (IERS Conventions 2010, Ch. 5, Table 5.1 / Eq. 5.21).
FRAME_BIAS_DALPHA0_MAS = -14.6
FRAME_BIAS_XI0_MAS = -16.6170
FRAME_BIAS_ETA0_MAS = -6.8192


def load_ephemeris(path: Path) -> SpiceKernel:
    """Open a JPL SPK kernel from ``path`` (no download), or raise ``SatsightError``."""
    path = Path(path)
    if not path.is_file():
        raise SatsightError(
            f"the planetary ephemeris {path} is missing; reinstall skyfield-data "
            "('pip install --force-reinstall skyfield-data'), which ships de421.bsp"
        )
    if path.parent == skyfield_data_dir():
        return skyfield_loader()(path.name)
    return SpiceKernel(str(path))


@lru_cache(maxsize=1)
def ephemeris() -> SpiceKernel:
    """The DE421 kernel bundled with skyfield-data, opened once and cached."""
    return load_ephemeris(skyfield_data_dir() / EPHEMERIS_FILE)


def clear_cache() -> None:
    """Close the cached kernel and forget the cached loader, timescale and ephemeris.

    The next call reloads everything from disk (used by tests; harmless otherwise).
    """
    if ephemeris.cache_info().currsize:
        ephemeris().close()
    ephemeris.cache_clear()
    timescale.cache_clear()
    skyfield_loader.cache_clear()


def _positions_gcrs_m(times: Time, name: str) -> np.ndarray:
    eph = ephemeris()
    try:
        # Geometric: both ends at the same instant (module docstring). Subtracting the two
        # vector sums drops their common segments (the Earth-Moon barycentre for the Moon).
        geometric = (eph[name] - eph["earth"]).at(times)
    except EphemerisRangeError as e:
        raise SatsightError(
            f"time outside the span of {EPHEMERIS_FILE} (1899-07-29 to 2053-10-09): {e}"
        ) from e
    pos = np.asarray(geometric.position.m, dtype=np.float64)
    return pos.reshape(3, -1).T.copy()


def sun_position_gcrs_m(times: Time) -> np.ndarray:
    """(N, 3) geocentric GCRS position of the Sun, m (geometric: no light time, no aberration).

    ``times``: a scalar (N = 1) or (N,) skyfield ``Time``, e.g. from
    :func:`satsight.ephemeris.time.epoch_times`.
    """
    return _positions_gcrs_m(times, "sun")


def moon_position_gcrs_m(times: Time) -> np.ndarray:
    """(N, 3) geocentric GCRS position of the Moon, m (geometric: no light time, no aberration).

    ``times``: a scalar (N = 1) or (N,) skyfield ``Time``.
    """
    return _positions_gcrs_m(times, "moon")


def sun_distance_au(times: Time) -> np.ndarray:
    """(N,) distance from the Earth's centre to the Sun's, AU (for 1/r^2 irradiance)."""
    return np.linalg.norm(sun_position_gcrs_m(times), axis=1) / AU_M


def _rot(axis: int, angle_rad: float) -> np.ndarray:
    """Ri(θ): rotation of the coordinate axes by θ about axis i (0 = x, 1 = y, 2 = z)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    j, k = (axis + 1) % 3, (axis + 2) % 3
    r = np.eye(3)
    r[j, j] = c
    r[j, k] = s
    r[k, j] = -s
    r[k, k] = c
    return r


@lru_cache(maxsize=1)
def _bias_matrix() -> np.ndarray:
    da0 = FRAME_BIAS_DALPHA0_MAS * _MAS_TO_RAD
    xi0 = FRAME_BIAS_XI0_MAS * _MAS_TO_RAD
    eta0 = FRAME_BIAS_ETA0_MAS * _MAS_TO_RAD
    b = _rot(0, -eta0) @ _rot(1, xi0) @ _rot(2, da0)
    b.flags.writeable = False
    return b


def eme2000_from_gcrs_matrix() -> np.ndarray:
    """(3, 3) frame-bias matrix B: ``r_eme2000 = B @ r_gcrs`` (constant, no time argument).

    Columns are the GCRS axes expressed in the mean equator and equinox of J2000.0. A
    fresh writable copy is returned.
    """
    return _bias_matrix().copy()


def gcrs_from_eme2000_matrix() -> np.ndarray:
    """(3, 3) inverse frame bias, ``r_gcrs = B.T @ r_eme2000``."""
    return _bias_matrix().T.copy()


def eme2000_from_gcrs(vectors: object) -> np.ndarray:
    """GCRS vectors (..., 3) -> mean equator and equinox of J2000.0, same unit and shape."""
    v = np.asarray(vectors, dtype=np.float64)
    if v.ndim == 0 or v.shape[-1] != 3:
        raise SatsightError(f"vectors must have shape (..., 3), got {v.shape}")
    return v @ _bias_matrix().T


def gcrs_from_eme2000(vectors: object) -> np.ndarray:
    """Mean equator and equinox of J2000.0 vectors (..., 3) -> GCRS, same unit and shape."""
    v = np.asarray(vectors, dtype=np.float64)
    if v.ndim == 0 or v.shape[-1] != 3:
        raise SatsightError(f"vectors must have shape (..., 3), got {v.shape}")
    return v @ _bias_matrix()
