"""Which V magnitude a catalogue star gets: Gaia's transform, or Hipparcos when Gaia's is bad.

The Gaia V (G - (G - V)(BP - RP), Riello et al. 2021, Table C.2) is used unless one of these
holds, in which case a star paired with Hipparcos takes V from Hp (``hipparcos_fallback``):

1. No BP/RP colour (the file stores 0 for a missing magnitude).
2. BP - RP outside [-0.5, 2.75], the range over which the G - V polynomial is used here
   (``GV_COLOUR_RANGE``): either a corrupt BP or RP (HIP 89258: BP - RP = 5.10 for a
   B - V = 1.5 star, clipped to 2.75 it gave V 1.5 mag too faint) or a very red star (Miras,
   carbon stars; R Dor's clipped colour gave V 2.3 mag too bright).
3. |V_gaia - V_hip| > 0.3 mag *and* the Gaia sources within 10 arcsec, their fluxes summed,
   are also more than 0.3 mag off V_hip. The measured scatter of V_gaia - V_hip over the
   108 297 paired stars with an in-range colour is 0.010 mag (1.4826 x median absolute
   deviation); the quoted scatters, 0.030 mag for G - V (Riello et al.) and 0.029 mag for the
   V - Hp fit, give 0.042 mag in quadrature: 0.3 mag is 7 of those and 30 of the measured
   one. The blend test keeps Gaia for resolved doubles whose combined light Hipparcos measured
   (its photometry integrates a 38 arcsec field, ESA 1997 Vol. 1 Sect. 2.2): 1755 of the 3050
   pairs beyond 0.3 mag are such doubles within 10 arcsec; the others (HIP 3843: G 1.3 mag
   fainter than Hp at a normal colour) have a bad Gaia G or a Gaia source that is the
   faint companion of a primary missing from the G < 10 file.

The BP/RP flux excess factor C = (I_BP + I_RP) / I_G (Riello et al. 2021, Sect. 6) is not
used: the pinned file holds only G, BP and RP magnitudes (no fluxes, no flags), and forming
C from them needs the three photometric zero points, which would add a dependence for a
test that criterion 3 already makes on every paired star with Hipparcos's independent Hp.

V from Hipparcos: V = Hp + dV, with dV a quadratic in B - V (fitted on the paired stars,
rms 0.029 mag) for V - I <= 2, and a quadratic in the Hipparcos V - I (CDS I/311 field
V-I) above: B - V saturates near 1.6 for M giants (Hipparcos lists B - V = 1.50 +- 0.51 for
R Dor and HIP 89258), while V - Hp keeps growing with V - I, to ~0.9 mag at V - I = 4.7. The
V - I fit is made at load time on the paired stars with V - I in [1.5, 5.5] and G > 4 (Gaia
saturates brighter), their Gaia V from the same polynomial evaluated for BP - RP up to 5; a
single red star's Gaia V is uncertain by a few tenths there, the fit to 8 700 of them (and
a 5-sigma clipping) is not.

Gaia stars without a Hipparcos partner keep Gaia's V: ``gaia_colour_clipped`` marks those
whose colour lies outside [-0.5, 2.75] (clipped; 4.5 % of the file, reddened giants with V
up to ~1 mag too bright), ``gaia_g_only`` those with no colour (V = G).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from satsight.sensor.star_photometry import (
    GV_COEFFS,
    GV_COLOUR_RANGE,
    V_HP_FIT_RANGE_BV,
    _clipped_polyfit,
)

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

V_SOURCE_NAMES = (
    "gaia_transform",
    "gaia_colour_clipped",
    "gaia_g_only",
    "hipparcos_fallback",
    "hipparcos_only",
)
"""Meaning of the catalogue's ``v_source`` codes 0-4 (see the module docstring)."""
GAIA_TRANSFORM, GAIA_COLOUR_CLIPPED, GAIA_G_ONLY, HIPPARCOS_FALLBACK, HIPPARCOS_ONLY = range(5)

GAIA_HIP_MAX_DELTA_V_MAG = 0.3
"""Largest |V_gaia - V_hip| (mag) for which a paired star keeps its Gaia V."""
BLEND_RADIUS_ARCSEC = 10.0
"""Gaia sources within this radius are summed when testing a pair against Hipparcos."""
V_I_SWITCH_MAG = 2.0
"""Above this Hipparcos V - I, V - Hp is taken from V - I rather than B - V."""
V_I_FIT_RANGE = (1.5, 5.5)
"""Range of V - I over which V - Hp is fitted as a quadratic in V - I (and clipped to)."""
V_I_FIT_MAX_BPRP = 5.0
"""Reddest BP - RP whose Gaia V enters the V - I fit."""
V_I_FIT_MIN_G = 4.0
"""Brightest G whose Gaia V enters the V - I fit (Gaia's photometry saturates brighter)."""


def fit_v_minus_hp_from_v_minus_i(
    g_mag: np.ndarray, bp_minus_rp: np.ndarray, v_minus_i: np.ndarray, hp_mag: np.ndarray
) -> dict[str, Any]:
    """Quadratic V - Hp in the Hipparcos V - I over [1.5, 5.5], fitted (three 5-sigma clipping
    passes) on paired stars, (K,) each, with V = G - (G - V)(BP - RP) for BP - RP in
    [-0.5, 5] and G > 4. Returns the coefficients (increasing powers), rms and count."""
    c = np.asarray(bp_minus_rp, dtype=np.float64)
    use = (
        (c >= GV_COLOUR_RANGE[0])
        & (c <= V_I_FIT_MAX_BPRP)
        & (g_mag > V_I_FIT_MIN_G)
        & (v_minus_i >= V_I_FIT_RANGE[0])
        & (v_minus_i <= V_I_FIT_RANGE[1])
    )
    v = g_mag[use] - np.polynomial.polynomial.polyval(c[use], GV_COEFFS)
    coeffs, rms, n = _clipped_polyfit(v_minus_i[use], v - hp_mag[use], 2)
    return {
        "v_minus_hp_from_v_minus_i": tuple(float(x) for x in coeffs),
        "v_minus_hp_from_v_minus_i_rms_mag": rms,
        "v_minus_hp_from_v_minus_i_n": n,
    }


def hipparcos_v(
    hp_mag: np.ndarray, b_minus_v: np.ndarray, v_minus_i: np.ndarray, fits: dict[str, Any]
) -> np.ndarray:
    """V = Hp + dV: dV from B - V (clipped to [-0.4, 2.0], 0 when unknown) where V - I <= 2,
    from V - I (clipped to [1.5, 5.5]) where V - I > 2."""
    dv_bv = np.polynomial.polynomial.polyval(
        np.clip(np.nan_to_num(b_minus_v), *V_HP_FIT_RANGE_BV), fits["v_minus_hp_from_bv"]
    )
    dv_vi = np.polynomial.polynomial.polyval(
        np.clip(v_minus_i, *V_I_FIT_RANGE), fits["v_minus_hp_from_v_minus_i"]
    )
    return hp_mag + np.where(v_minus_i > V_I_SWITCH_MAG, dv_vi, dv_bv)


def choose_v(
    v_gaia: np.ndarray,
    bp_minus_rp: np.ndarray,
    has_colour: np.ndarray,
    v_hip: np.ndarray,
    u_gaia: np.ndarray,
    tree: cKDTree,
    tree_index: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(V, v_source code) for the Gaia records, (N,) each.

    v_gaia, bp_minus_rp, has_colour: Gaia V, colour (NaN if none) and its presence.
    v_hip: V from Hipparcos of the paired star, NaN for an unpaired source. u_gaia: (N, 3)
    unit vectors; ``tree`` a cKDTree of ``u_gaia[tree_index]`` (the real Gaia sources).
    """
    paired = np.isfinite(v_hip)
    in_range = has_colour & (bp_minus_rp >= GV_COLOUR_RANGE[0])
    in_range &= bp_minus_rp <= GV_COLOUR_RANGE[1]
    source = np.where(
        in_range, GAIA_TRANSFORM, np.where(has_colour, GAIA_COLOUR_CLIPPED, GAIA_G_ONLY)
    ).astype(np.int8)
    bad = paired & ~in_range
    suspect = np.flatnonzero(
        paired & in_range & (np.abs(v_gaia - v_hip) > GAIA_HIP_MAX_DELTA_V_MAG)
    )
    if suspect.size:
        chord = 2.0 * math.sin(0.5 * BLEND_RADIUS_ARCSEC * math.pi / 648000.0)
        near = tree.query_ball_point(u_gaia[suspect], chord)
        flux = 10.0 ** (-0.4 * v_gaia)
        blend = np.array([flux[tree_index[n]].sum() if n else 0.0 for n in near])
        blend = np.maximum(blend, flux[suspect])  # the source itself, whatever the tree holds
        v_blend = -2.5 * np.log10(blend)
        bad[suspect] = np.abs(v_blend - v_hip[suspect]) > GAIA_HIP_MAX_DELTA_V_MAG
    v = np.where(bad, v_hip, v_gaia)
    source[bad] = HIPPARCOS_FALLBACK
    return v, source
