"""Planck's law (satsight.lighting.blackbody) against its closed-form integrals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.constants as const
from scipy.integrate import quad

from satsight.lighting.blackbody import planck_exitance_w_m2_per_m, planck_shape_per_m5


@pytest.mark.parametrize("temperature_k", [3000.0, 5778.0, 10000.0])
def test_exitance_integrates_to_stefan_boltzmann(temperature_k):
    # int_0^inf pi B_lambda dlambda = sigma T^4; quad over x = log(lambda) keeps the peak
    # (Wien: 2.898e-3 m K / T) resolved; quad's own error bound is ~1e-10 relative.
    def integrand(log_lam):
        lam = np.exp(log_lam)
        return float(planck_exitance_w_m2_per_m(lam, temperature_k)) * lam

    total, _ = quad(integrand, np.log(1e-8), np.log(1e-2), limit=200, epsabs=0, epsrel=1e-10)
    assert total == pytest.approx(const.Stefan_Boltzmann * temperature_k**4, rel=1e-8)


@pytest.mark.parametrize("temperature_k", [3000.0, 5778.0])
def test_shape_peaks_at_wiens_wavelength(temperature_k):
    lam = np.linspace(0.5, 1.5, 200_001) * const.Wien / temperature_k
    peak = lam[np.argmax(planck_shape_per_m5(lam, temperature_k))]
    # The grid step is 5e-6 of the peak wavelength.
    assert peak == pytest.approx(const.Wien / temperature_k, rel=1e-5)


def test_wien_tail_underflows_to_zero_without_warnings():
    assert planck_shape_per_m5(np.array([1e-9]), 300.0)[0] == 0.0
