"""Planck's law, once: the spectral shape of a black body and its spectral exitance.

``B_lambda(T) = 2 h c^2 / (lambda^5 (exp(c2 / (lambda T)) - 1))`` with the second radiation
constant ``c2 = h c / k`` (CODATA exact SI constants, ``satsight.constants``). The solar
spectrum's black-body option, the stars' colours and the stars' PSF weights all use it.
"""

from __future__ import annotations

import math

import numpy as np

from satsight.constants import BOLTZMANN_J_K, PLANCK_J_S, SPEED_OF_LIGHT_M_S

#: Second radiation constant c2 = h c / k, m K.
SECOND_RADIATION_CONSTANT_M_K = PLANCK_J_S * SPEED_OF_LIGHT_M_S / BOLTZMANN_J_K
#: First radiation constant for spectral exitance, c1 = 2 pi h c^2, W m^2.
FIRST_RADIATION_CONSTANT_W_M2 = 2.0 * math.pi * PLANCK_J_S * SPEED_OF_LIGHT_M_S**2


def planck_shape_per_m5(wavelength_m: np.ndarray, temperature_k: np.ndarray | float) -> np.ndarray:
    """``B_lambda(T) / (2 h c^2) = lambda^-5 / (exp(c2 / (lambda T)) - 1)``, m^-5.

    wavelength_m and temperature_k broadcast against each other. Far into the Wien tail the
    exponential overflows and the shape is 0.
    """
    lam = np.asarray(wavelength_m, dtype=np.float64)
    with np.errstate(over="ignore"):
        return lam**-5 / np.expm1(SECOND_RADIATION_CONSTANT_M_K / (lam * temperature_k))


def planck_exitance_w_m2_per_m(wavelength_m: np.ndarray, temperature_k: float) -> np.ndarray:
    """Spectral exitance ``pi B_lambda(T)`` of a black body, W m^-2 m^-1 (any shape of
    ``wavelength_m``, m). Its integral over all wavelengths is ``sigma T^4``."""
    return FIRST_RADIATION_CONSTANT_W_M2 * planck_shape_per_m5(wavelength_m, temperature_k)
