"""satsight.constants against their published values."""

from __future__ import annotations

import pytest

from satsight import constants


def test_wgs84_semi_minor_axis_matches_the_published_value():
    # NIMA TR8350.2, 3rd ed., Table 3.3: b = 6356752.3142 m (to 0.1 mm as tabulated).
    assert constants.WGS84_SEMI_MINOR_AXIS_M == pytest.approx(6_356_752.3142, abs=1e-4)


def test_the_earths_equatorial_radius_is_the_wgs84_semi_major_axis():
    assert constants.EARTH_EQUATORIAL_RADIUS_M == constants.WGS84_SEMI_MAJOR_AXIS_M == 6_378_137.0


def test_codata_constants_are_the_exact_si_values():
    # SI 2019 defining constants (exact).
    assert constants.PLANCK_J_S == 6.62607015e-34
    assert constants.SPEED_OF_LIGHT_M_S == 299_792_458.0
    assert constants.BOLTZMANN_J_K == 1.380649e-23


def test_the_stefan_boltzmann_constant_is_codatas():
    # CODATA 2018 (exact in the SI since 2019, to the ten digits given): 5.670374419e-8.
    import scipy.constants

    assert constants.STEFAN_BOLTZMANN_W_M2_K4 == pytest.approx(5.670374419e-8, rel=1e-10)
    assert constants.STEFAN_BOLTZMANN_W_M2_K4 == pytest.approx(
        scipy.constants.Stefan_Boltzmann, rel=1e-15
    )
