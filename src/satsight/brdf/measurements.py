"""Measured BRDF tables: the CSV format that ``satsight fit-brdf`` reads.

Format (one measurement per row, comma-separated, UTF-8)::

    # material: white paint, sample 3          <- optional "# key: value" metadata lines
    # source: goniometer run 2024-05-02
    # licence: CC-BY-4.0
    theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,band,brdf_per_sr
    30,0,30,180,R,1.214
    30,0,30,180,G,1.190
    ...

Columns (header names are exact, in any order; other columns are ignored):

* ``theta_i_deg``, ``phi_i_deg``: direction towards the light source, polar angle from the
  surface normal in [0, 90) degrees and azimuth in [-360, 360] degrees.
* ``theta_o_deg``, ``phi_o_deg``: direction towards the detector, same ranges. The
  specular (mirror) geometry is theta_o = theta_i, phi_o = phi_i + 180 deg.
* exactly one of ``wavelength_nm`` (a number > 0) or ``band`` (a label such as ``R``, ``G``,
  ``B`` or ``V``): the spectral channel. Every distinct value is one channel of the fit.
* ``brdf_per_sr``: the BRDF f_r in sr^-1 (finite, >= 0); ``brdf_sr^-1`` and ``brdf_sr-1``
  are accepted as the same column.
* optional ``uncertainty_per_sr``: the standard uncertainty of the BRDF value (> 0), used
  as the weight 1 / sigma in the fit.

Blank lines and lines that start with ``#`` are skipped; ``# key: value`` lines before the
header become the table's metadata (kept as the fit's provenance). Malformed files raise
``SatsightError`` naming the file, the line number and what is wrong.

Inside, angles are in radians (SI), as the rest of satsight.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from satsight.brdf.models import unit_vectors_from_angles
from satsight.errors import SatsightError

ANGLE_COLUMNS = ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")
BRDF_COLUMN = "brdf_per_sr"
BRDF_ALIASES = ("brdf_sr^-1", "brdf_sr-1")
UNCERTAINTY_COLUMN = "uncertainty_per_sr"
CHANNEL_COLUMNS = ("wavelength_nm", "band")
MAX_THETA_DEG = 90.0
MAX_ABS_PHI_DEG = 360.0

_FORMAT_HINT = (
    "expected a header with theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg, one of "
    "wavelength_nm or band, and brdf_per_sr (see satsight.brdf.measurements)"
)


@dataclass(frozen=True)
class BrdfMeasurements:
    """A measured BRDF table, one entry per row of the file.

    Angles (N,) in radians: theta_i_rad / phi_i_rad towards the source, theta_o_rad /
    phi_o_rad towards the detector (polar angle from the normal, azimuth from +x).
    brdf_per_sr (N,): f_r in sr^-1. channel (N,) int: index into channel_names, the
    distinct wavelengths (as text, in nm) or band labels in the order first met;
    channel_kind: "wavelength_nm" or "band". uncertainty_per_sr: (N,) or None.
    line_numbers (N,): the line of each row in the file (1-based). metadata: the
    ``# key: value`` lines before the header. path: the file read.
    """

    path: Path
    theta_i_rad: np.ndarray
    phi_i_rad: np.ndarray
    theta_o_rad: np.ndarray
    phi_o_rad: np.ndarray
    brdf_per_sr: np.ndarray
    channel: np.ndarray
    channel_names: tuple[str, ...]
    channel_kind: str
    uncertainty_per_sr: np.ndarray | None = None
    line_numbers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def size(self) -> int:
        """Number of measurements."""
        return int(self.brdf_per_sr.size)

    @property
    def n_channels(self) -> int:
        return len(self.channel_names)

    def wi(self) -> np.ndarray:
        """(N, 3) unit vectors towards the source in the surface frame (normal +z)."""
        return unit_vectors_from_angles(self.theta_i_rad, self.phi_i_rad)

    def wo(self) -> np.ndarray:
        """(N, 3) unit vectors towards the detector in the surface frame (normal +z)."""
        return unit_vectors_from_angles(self.theta_o_rad, self.phi_o_rad)


def _fail(path: Path, line: int | None, what: str) -> SatsightError:
    where = f"{path}" if line is None else f"{path}, line {line}"
    return SatsightError(f"{where}: {what}")


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _fail(path, line, f"column {column} must be a number, got {text.strip()!r}") from None
    if not math.isfinite(value):
        raise _fail(path, line, f"column {column} must be a finite number, got {text.strip()!r}")
    return value


def _header_index(path: Path, line: int, header: list[str]) -> dict[str, int]:
    names = [h.strip() for h in header]
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        key = BRDF_COLUMN if name in BRDF_ALIASES else name
        if key in index:
            raise _fail(path, line, f"column {name} appears twice in the header")
        index[key] = i
    missing = [c for c in (*ANGLE_COLUMNS, BRDF_COLUMN) if c not in index]
    if missing:
        raise _fail(
            path,
            line,
            f"missing column {', '.join(missing)} in the header {','.join(names)}; " + _FORMAT_HINT,
        )
    channels = [c for c in CHANNEL_COLUMNS if c in index]
    if len(channels) != 1:
        what = "both" if channels else "neither of"
        raise _fail(
            path,
            line,
            f"the header has {what} wavelength_nm and band; give exactly one (the spectral "
            "channel of each row)",
        )
    return index


def read_brdf_csv(path: str | Path) -> BrdfMeasurements:
    """Read a measured BRDF table (format in the module docstring).

    Raises ``SatsightError`` naming the file and line for: a missing file, an empty file or
    one without data rows, a missing column, a row with too few fields, a non-numeric or
    non-finite value, an angle out of range (theta in [0, 90), phi in [-360, 360]), a
    negative BRDF, a wavelength <= 0, an empty band label, an uncertainty <= 0.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise _fail(path, None, "no such file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise _fail(path, None, f"cannot read the file ({err})") from None

    metadata: dict[str, str] = {}
    index: dict[str, int] | None = None
    channel_kind = ""
    rows: list[tuple[float, ...]] = []
    channels: list[str] = []
    uncertainties: list[float] = []
    lines: list[int] = []
    for line_number, fields in _records(text):
        if fields is None:
            continue
        if isinstance(fields, str):  # a comment
            if index is None and ":" in fields:
                key, _, value = fields.partition(":")
                if key.strip():
                    metadata[key.strip()] = value.strip()
            continue
        if index is None:
            index = _header_index(path, line_number, fields)
            channel_kind = next(c for c in CHANNEL_COLUMNS if c in index)
            continue
        needed = max(index.values()) + 1
        if len(fields) < needed:
            raise _fail(
                path,
                line_number,
                f"expected at least {needed} comma-separated fields, got {len(fields)}",
            )
        values = {c: _number(path, line_number, c, fields[index[c]]) for c in ANGLE_COLUMNS}
        for c in ("theta_i_deg", "theta_o_deg"):
            if not (0.0 <= values[c] < MAX_THETA_DEG):
                raise _fail(
                    path,
                    line_number,
                    f"angle out of range: {c} = {values[c]:g}, expected 0 <= {c} < 90 "
                    "(polar angle from the surface normal)",
                )
        for c in ("phi_i_deg", "phi_o_deg"):
            if abs(values[c]) > MAX_ABS_PHI_DEG:
                raise _fail(
                    path,
                    line_number,
                    f"angle out of range: {c} = {values[c]:g}, expected -360 <= {c} <= 360",
                )
        brdf = _number(path, line_number, BRDF_COLUMN, fields[index[BRDF_COLUMN]])
        if brdf < 0.0:
            raise _fail(
                path, line_number, f"negative BRDF: {BRDF_COLUMN} = {brdf:g}, expected >= 0"
            )
        raw_channel = fields[index[channel_kind]].strip()
        if channel_kind == "wavelength_nm":
            wavelength = _number(path, line_number, channel_kind, raw_channel)
            if wavelength <= 0.0:
                raise _fail(path, line_number, f"wavelength_nm must be > 0, got {wavelength:g}")
            label = f"{wavelength:g}"
        else:
            if not raw_channel:
                raise _fail(path, line_number, "empty band label")
            label = raw_channel
        if UNCERTAINTY_COLUMN in index:
            sigma = _number(
                path, line_number, UNCERTAINTY_COLUMN, fields[index[UNCERTAINTY_COLUMN]]
            )
            if sigma <= 0.0:
                raise _fail(path, line_number, f"{UNCERTAINTY_COLUMN} must be > 0, got {sigma:g}")
            uncertainties.append(sigma)
        rows.append((*(values[c] for c in ANGLE_COLUMNS), brdf))
        channels.append(label)
        lines.append(line_number)

    if index is None:
        raise _fail(path, None, "empty file: no header line; " + _FORMAT_HINT)
    if not rows:
        raise _fail(path, None, "no data rows after the header")

    table = np.array(rows, dtype=np.float64)
    names = tuple(dict.fromkeys(channels))
    lookup = {name: i for i, name in enumerate(names)}
    return BrdfMeasurements(
        path=path,
        theta_i_rad=np.radians(table[:, 0]),
        phi_i_rad=np.radians(table[:, 1]),
        theta_o_rad=np.radians(table[:, 2]),
        phi_o_rad=np.radians(table[:, 3]),
        brdf_per_sr=table[:, 4],
        channel=np.array([lookup[c] for c in channels], dtype=np.int64),
        channel_names=names,
        channel_kind=channel_kind,
        uncertainty_per_sr=np.array(uncertainties) if uncertainties else None,
        line_numbers=np.array(lines, dtype=np.int64),
        metadata=metadata,
    )


def measurements_from_degrees(
    theta_i_deg,
    phi_i_deg,
    theta_o_deg,
    phi_o_deg,
    brdf_per_sr,
    channel_labels,
    channel_kind: str = "band",
    uncertainty_per_sr=None,
    metadata: dict[str, str] | None = None,
    path: str | Path = "<memory>",
) -> BrdfMeasurements:
    """A table from arrays (N,): angles in degrees, BRDF in sr^-1, one channel label per
    row (band labels or wavelengths in nm). No range checks: for data made in code."""
    if channel_kind not in CHANNEL_COLUMNS:
        raise SatsightError(f"channel_kind must be one of {CHANNEL_COLUMNS}, got {channel_kind!r}")
    labels = [
        f"{float(c):g}" if channel_kind == "wavelength_nm" else str(c) for c in channel_labels
    ]
    names = tuple(dict.fromkeys(labels))
    lookup = {name: i for i, name in enumerate(names)}
    brdf = np.asarray(brdf_per_sr, dtype=np.float64)
    return BrdfMeasurements(
        path=Path(path),
        theta_i_rad=np.radians(np.asarray(theta_i_deg, dtype=np.float64)),
        phi_i_rad=np.radians(np.asarray(phi_i_deg, dtype=np.float64)),
        theta_o_rad=np.radians(np.asarray(theta_o_deg, dtype=np.float64)),
        phi_o_rad=np.radians(np.asarray(phi_o_deg, dtype=np.float64)),
        brdf_per_sr=brdf,
        channel=np.array([lookup[c] for c in labels], dtype=np.int64),
        channel_names=names,
        channel_kind=channel_kind,
        uncertainty_per_sr=None
        if uncertainty_per_sr is None
        else np.asarray(uncertainty_per_sr, dtype=np.float64),
        line_numbers=np.zeros(brdf.size, dtype=np.int64),
        metadata=dict(metadata or {}),
    )


def _records(text: str):
    """(line number, fields) per physical line: fields None for a blank line, the comment
    text (a str) for a '#' line, else the list of comma-separated fields."""
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            yield number, None
        elif stripped.startswith("#"):
            yield number, stripped[1:].strip()
        else:
            yield number, next(csv.reader([line]))


def write_brdf_csv(
    path: str | Path,
    measurements: BrdfMeasurements,
    brdf_per_sr: np.ndarray | None = None,
    metadata: dict[str, str] | None = None,
) -> Path:
    """Write a table in the format read by ``read_brdf_csv`` (angles in degrees, BRDF with
    8 significant digits); brdf_per_sr replaces the measured values when given."""
    path = Path(path)
    values = measurements.brdf_per_sr if brdf_per_sr is None else np.asarray(brdf_per_sr)
    meta = measurements.metadata if metadata is None else metadata
    header = [*ANGLE_COLUMNS, measurements.channel_kind, BRDF_COLUMN]
    if measurements.uncertainty_per_sr is not None:
        header.append(UNCERTAINTY_COLUMN)
    out = [f"# {key}: {value}" for key, value in meta.items()]
    out.append(",".join(header))
    angles = np.degrees(
        np.stack(
            [
                measurements.theta_i_rad,
                measurements.phi_i_rad,
                measurements.theta_o_rad,
                measurements.phi_o_rad,
            ],
            axis=1,
        )
    )
    for k in range(measurements.size):
        fields = [f"{a:.10g}" for a in angles[k]]
        fields.append(measurements.channel_names[measurements.channel[k]])
        fields.append(f"{values[k]:.8g}")
        if measurements.uncertainty_per_sr is not None:
            fields.append(f"{measurements.uncertainty_per_sr[k]:.8g}")
        out.append(",".join(fields))
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path
