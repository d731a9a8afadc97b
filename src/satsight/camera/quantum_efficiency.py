"""Spectral quantum efficiency of the detector, QE(lambda) in electrons per photon.

Two curves:

* ``"ccd231_84"``: the default detector, a Teledyne e2v CCD231-84 back-illuminated CCD
  with the astro multi-2 coating, from ``camera/data/ccd231_84_astro_multi2_qe.csv``
  (350-1100 nm, linear between samples, 0 outside). The table is a documented
  *approximation* of the datasheet's typical curve, not its tabulated values; its header
  says so and why.
* ``"flat"``: QE = 1 at every wavelength, for band integrals that weight by photons only.

Used by :mod:`satsight.scene.band_reflectance` to weight reflectance spectra by what the
detector counts. Wavelengths in nm (how QE curves are quoted); QE dimensionless in [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from satsight.errors import SatsightError

QE_CURVES: tuple[str, ...] = ("ccd231_84", "flat")
DEFAULT_QE = "ccd231_84"
_FILES = {"ccd231_84": "ccd231_84_astro_multi2_qe.csv"}
_COLUMNS = "wavelength_nm,quantum_efficiency"


@dataclass(frozen=True)
class QuantumEfficiency:
    """A QE curve: (K,) increasing wavelengths in nm and (K,) QE in [0, 1] (linear between
    samples, 0 outside), or ``flat`` (QE = 1 everywhere, the arrays empty)."""

    name: str
    wavelength_nm: np.ndarray
    qe: np.ndarray
    source: str
    flat: bool = False

    def __call__(self, wavelength_nm: np.ndarray) -> np.ndarray:
        """QE at ``wavelength_nm`` (any shape, nm)."""
        wl = np.asarray(wavelength_nm, dtype=np.float64)
        if self.flat:
            return np.ones_like(wl)
        return np.interp(wl, self.wavelength_nm, self.qe, left=0.0, right=0.0)


def _parse(text: str, label: str) -> tuple[np.ndarray, np.ndarray]:
    lines = [s.strip() for s in text.splitlines() if s.strip() and not s.startswith("#")]
    if not lines or lines[0] != _COLUMNS:
        raise SatsightError(f"{label}: expected the column header '{_COLUMNS}'")
    table = np.array([[float(v) for v in s.split(",")] for s in lines[1:]], dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != 2 or not np.all(np.diff(table[:, 0]) > 0):
        raise SatsightError(f"{label}: expected rows 'wavelength_nm,quantum_efficiency' in order")
    if not np.all((table[:, 1] >= 0.0) & (table[:, 1] <= 1.0)):
        raise SatsightError(f"{label}: quantum efficiency must be in [0, 1]")
    return table[:, 0], table[:, 1]


@lru_cache(maxsize=4)
def load_quantum_efficiency(name: str = DEFAULT_QE) -> QuantumEfficiency:
    """The named QE curve (``"ccd231_84"`` or ``"flat"``)."""
    if name == "flat":
        empty = np.zeros(0)
        return QuantumEfficiency("flat", empty, empty, "QE = 1 at all wavelengths", flat=True)
    if name not in _FILES:
        raise SatsightError(f"unknown QE curve '{name}'; choose one of {', '.join(QE_CURVES)}")
    path = resources.files("satsight.camera") / "data" / _FILES[name]
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SatsightError(f"QE file {_FILES[name]} cannot be read ({exc}); reinstall") from exc
    wl, qe = _parse(text, _FILES[name])
    wl.setflags(write=False)
    qe.setflags(write=False)
    source = (
        "Teledyne e2v CCD231-84, back-illuminated, astro multi-2 coating: documented "
        "approximation of the datasheet's typical curve (see the data file's header)"
    )
    return QuantumEfficiency(name, wl, qe, source)


def resolve_quantum_efficiency(qe: str | QuantumEfficiency) -> QuantumEfficiency:
    """A QuantumEfficiency from a curve name or an instance."""
    if isinstance(qe, QuantumEfficiency):
        return qe
    return load_quantum_efficiency(str(qe))
