"""The Earth's surface albedo map: land, ocean, polar ice and a seeded cloud field.

Albedo per 0.1 deg cell (1800 x 3600, ``AlbedoMap`` convention):

    rho = (1 - c) [f rho_land + (1 - f) rho_ocean] + c rho_cloud

* f, the land fraction of the cell: the mean of the 1 km GLOBE land/sea mask (NOAA
  National Geophysical Data Center, GLOBE v1.0, 1999) as shipped by the
  ``global-land-mask`` package (MIT licence), over the cell's 12 x 12 samples. Land south
  of 60 deg S (Antarctica) takes the ice albedo.
* c, the cloud cover of the cell: a seeded fractal field on the unit sphere (value noise
  on 3-D lattices, 7 octaves from 6 cells across the Earth, amplitude 0.65 per octave),
  passed through a linear ramp whose threshold gives the mean cover ``cloud_fraction``
  (default 0.67, the MODIS global cloud fraction: King et al. 2013, IEEE TGRS 51, 3826).
  Cloud systems are thereby spatially coherent at 100-3000 km scales, but they follow no
  real weather and no climatological latitude pattern: a stand-in, not a forecast.
* Albedos (broadband, Lambertian, the same in every channel): ocean 0.06 (Payne 1972,
  J. Atmos. Sci. 29, 959), land 0.25 (between vegetated surfaces ~0.15 and deserts ~0.35),
  ice 0.80 (fresh snow 0.8-0.9: Warren 1982, Rev. Geophys. 20, 67). The cloud albedo,
  unless given, is calibrated so that the map's area mean is the Earth's Bond albedo 0.30
  (Stephens et al. 2015, Rev. Geophys. 53, 141); with the defaults it comes out near 0.39.

The map is built once (about 10 s and 1 GB while the 1 km mask is read) and cached as a
compressed .npz under ``$XDG_CACHE_HOME/satsight`` (or ``~/.cache/satsight``); the cache
key holds every parameter. The mask's per-cell sample counts are cached there too (exact,
3 MB), so a map with other parameters is built in a second, not ten.
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections import OrderedDict
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from satsight.disk_cache import cache_dir, write_npz_atomically
from satsight.errors import SatsightError
from satsight.lighting.scene_bodies import AlbedoMap

MAP_ROWS, MAP_COLS = 1800, 3600
OCEAN_ALBEDO = 0.06
LAND_ALBEDO = 0.25
ICE_ALBEDO = 0.80
CLOUD_FRACTION = 0.67
BOND_ALBEDO = 0.30
_ICE_LATITUDE_DEG = -60.0
_OCTAVES = 7
_PERSISTENCE = 0.65
_CACHE_VERSION = 2


@dataclass(frozen=True)
class EarthSurfaceModel:
    """Parameters of the albedo map (see the module docstring)."""

    land_albedo: float = LAND_ALBEDO
    ocean_albedo: float = OCEAN_ALBEDO
    ice_albedo: float = ICE_ALBEDO
    cloud_fraction: float = CLOUD_FRACTION
    cloud_albedo: float | None = None
    cloud_seed: int = 0

    def __post_init__(self) -> None:
        for name in ("land_albedo", "ocean_albedo", "ice_albedo", "cloud_fraction"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise SatsightError(f"earth surface: {name} must be in [0, 1], got {value}")
        if self.cloud_albedo is not None and not 0.0 <= self.cloud_albedo <= 1.0:
            raise SatsightError("earth surface: cloud_albedo must be in [0, 1]")


def _globe_mask_path() -> tuple[Path, str]:
    """The GLOBE mask file of the global-land-mask package and the package's version (found
    without importing the package, which reads the whole mask when imported)."""
    from importlib.metadata import PackageNotFoundError, version
    from importlib.util import find_spec

    spec = find_spec("global_land_mask")
    try:
        package_version = version("global-land-mask")
    except PackageNotFoundError:
        spec = None
    if spec is None or not spec.submodule_search_locations:
        raise SatsightError(
            "the Earth's albedo map needs the 'global-land-mask' package "
            "(pip install global-land-mask), or set earth.surface: uniform"
        )
    folder = Path(next(iter(spec.submodule_search_locations)))
    return folder / "globe_combined_mask_compressed.npz", package_version


def _ocean_counts(mask_path: Path) -> np.ndarray:
    """(1800, 3600) uint8: how many of the 12 x 12 GLOBE 1 km samples of each 0.1 deg cell
    are ocean (0 to 144)."""
    with np.load(str(mask_path)) as data:
        ocean = data["mask"]  # True over the ocean, rows from +90 deg, columns from -180 deg
    rows, cols = ocean.shape
    fy, fx = rows // MAP_ROWS, cols // MAP_COLS
    counts = np.empty((MAP_ROWS, MAP_COLS), dtype=np.uint8)
    for start in range(0, MAP_ROWS, 100):  # in bands, to keep the copies small
        band = ocean[start * fy : (start + 100) * fy]
        counts[start : start + 100] = band.reshape(-1, fy, MAP_COLS, fx).sum(
            axis=(1, 3), dtype=np.uint8
        )
    return counts


def land_fraction() -> np.ndarray:
    """(1800, 3600) float32 land fraction per 0.1 deg cell from the 1 km GLOBE mask.

    Each cell is 1 - (ocean samples) / 144, exactly rounded to float32. Reading the mask
    takes seconds (933 M samples, zlib-compressed), so the sample counts are cached, 3 MB
    exact, beside the albedo maps (keyed by the package's version).
    """
    mask_path, package_version = _globe_mask_path()
    path = cache_dir() / f"globe_ocean_counts_{package_version}_v{_CACHE_VERSION}.npz"
    counts = None
    if path.exists():
        try:
            with np.load(path) as data:
                counts = data["ocean_counts"]
            if counts.shape != (MAP_ROWS, MAP_COLS) or counts.dtype != np.uint8:
                counts = None
        except (OSError, ValueError, KeyError):
            counts = None  # a damaged cache file is rebuilt
    if counts is None:
        counts = _ocean_counts(mask_path)
        write_npz_atomically(path, ocean_counts=counts)
    samples = np.float32(np.uint8(144))
    return np.float32(1.0) - counts.astype(np.float32) / samples


def _cell_directions() -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (rows, cols, 3) of the cell centres and their latitudes (deg)."""
    lat = 90.0 - (np.arange(MAP_ROWS) + 0.5) * 180.0 / MAP_ROWS
    lon = -180.0 + (np.arange(MAP_COLS) + 0.5) * 360.0 / MAP_COLS
    la, lo = np.radians(lat)[:, None], np.radians(lon)[None, :]
    xyz = np.stack(
        np.broadcast_arrays(np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)),
        axis=-1,
    ).astype(np.float32)
    return xyz, lat


def cloud_noise(seed: int) -> np.ndarray:
    """(1800, 3600) float32 fractal value noise on the unit sphere, zero mean, seeded."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x434C4F55]))
    xyz, _ = _cell_directions()
    total = np.zeros((MAP_ROWS, MAP_COLS), dtype=np.float32)
    for octave in range(_OCTAVES):
        cells = 6 * 2**octave  # lattice cells across the sphere's diameter
        lattice = rng.standard_normal((cells + 2,) * 3).astype(np.float32)
        pos = (xyz + 1.0) * (0.5 * cells)
        i0 = np.minimum(np.floor(pos).astype(np.int32), cells)
        f = pos - i0
        f = f * f * (3.0 - 2.0 * f)  # smooth interpolation weights
        value = np.zeros_like(total)
        for corner in range(8):
            dx, dy, dz = corner & 1, (corner >> 1) & 1, (corner >> 2) & 1
            w = (
                (f[..., 0] if dx else 1 - f[..., 0])
                * (f[..., 1] if dy else 1 - f[..., 1])
                * (f[..., 2] if dz else 1 - f[..., 2])
            )
            value += w * lattice[i0[..., 0] + dx, i0[..., 1] + dy, i0[..., 2] + dz]
        total += value * _PERSISTENCE**octave
    return total - total.mean()


@functools.lru_cache(maxsize=2)
def _kept_cloud_noise(seed: int) -> np.ndarray:
    """``cloud_noise(seed)``, read-only, kept for the next map of the same pattern (a
    randomised cloud cover builds one map per level from it: ~1.5 s, not ~14 s)."""
    noise = cloud_noise(seed)
    noise.flags.writeable = False
    return noise


def cloud_cover(noise: np.ndarray, fraction: float, weights: np.ndarray) -> np.ndarray:
    """Cloud cover in [0, 1] from the noise: a linear ramp of width 0.3 noise std around a
    threshold chosen (bisection) so that the area-weighted mean cover is ``fraction``."""
    width = 0.3 * float(noise.std())

    def cover(threshold: float) -> np.ndarray:
        return np.clip((noise - threshold) / width + 0.5, 0.0, 1.0)

    lo, hi = float(noise.min()) - width, float(noise.max()) + width
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if np.average(cover(mid), weights=weights) > fraction:
            lo = mid
        else:
            hi = mid
    return cover(0.5 * (lo + hi)).astype(np.float32)


def build_albedo_map(model: EarthSurfaceModel) -> AlbedoMap:
    """The albedo map of ``model`` (uncached; see ``earth_albedo_map``)."""
    land = land_fraction()
    _, lat = _cell_directions()
    area = np.broadcast_to(np.cos(np.radians(lat))[:, None], land.shape)
    land_albedo = np.where(lat[:, None] < _ICE_LATITUDE_DEG, model.ice_albedo, model.land_albedo)
    surface = land * land_albedo + (1.0 - land) * model.ocean_albedo
    cover = cloud_cover(_kept_cloud_noise(model.cloud_seed), model.cloud_fraction, area)
    cloud_albedo = model.cloud_albedo
    if cloud_albedo is None:
        clear = float(np.average((1.0 - cover) * surface, weights=area))
        mean_cover = float(np.average(cover, weights=area))
        cloud_albedo = (BOND_ALBEDO - clear) / max(mean_cover, 1e-6)
        if not 0.0 <= cloud_albedo <= 1.0:
            raise SatsightError(
                f"earth surface: no cloud albedo in [0, 1] brings the mean albedo to "
                f"{BOND_ALBEDO} with these values (it would be {cloud_albedo:.3f}); give "
                "cloud_albedo"
            )
    albedo = (1.0 - cover) * surface + cover * cloud_albedo
    mean = float(np.average(albedo, weights=area))
    description = (
        "GLOBE 1 km land/sea mask (global-land-mask package) at 0.1 deg; "
        + json.dumps({**asdict(model), "cloud_albedo": round(cloud_albedo, 5)})
        + f"; area-mean albedo {mean:.4f}"
    )
    return AlbedoMap(albedo.astype(np.float32)[..., None], description)  # a grey map


# Maps kept in memory, the most recently used last: a randomised cloud cover draws one map
# per level and pattern (78 MB each), so only the last few stay.
_MEMORY: OrderedDict[str, AlbedoMap] = OrderedDict()
_MEMORY_MAPS = 4


def earth_albedo_map(model: EarthSurfaceModel | None = None) -> AlbedoMap:
    """The albedo map of ``model`` (defaults if None), from memory, the disk cache, or
    built and cached (written atomically, so concurrent workers are safe)."""
    model = model or EarthSurfaceModel()
    key = hashlib.sha256(
        json.dumps({**asdict(model), "v": _CACHE_VERSION}, sort_keys=True).encode()
    ).hexdigest()[:16]
    if key in _MEMORY:
        _MEMORY.move_to_end(key)
        return _MEMORY[key]
    path = cache_dir() / f"earth_albedo_{key}.npz"
    albedo_map = None
    if path.exists():
        try:
            with np.load(path) as data:
                grey = data["albedo"].astype(np.float32) / 65535.0
                albedo_map = AlbedoMap(grey[..., None], str(data["about"]))
        except (OSError, ValueError, KeyError):
            albedo_map = None  # a damaged cache file is rebuilt
    if albedo_map is None:
        albedo_map = build_albedo_map(model)
        grey = np.round(albedo_map.albedo_rgb[..., 0] * 65535.0).astype(np.uint16)
        write_npz_atomically(path, albedo=grey, about=np.array(albedo_map.description))
        # What is kept is the 16-bit value, so a fresh build and a cache read agree.
        albedo_map = AlbedoMap(
            (grey.astype(np.float32) / 65535.0)[..., None], albedo_map.description
        )
    _MEMORY[key] = albedo_map
    while len(_MEMORY) > _MEMORY_MAPS:
        _MEMORY.popitem(last=False)
    return albedo_map


def map_mean_albedo(albedo_map: AlbedoMap) -> float:
    """Area-weighted mean albedo of a map (green channel; a grey map's one)."""
    rows, _, channels = albedo_map.albedo_rgb.shape
    lat = 90.0 - (np.arange(rows) + 0.5) * 180.0 / rows
    weights = np.cos(np.radians(lat))[:, None] * np.ones(albedo_map.albedo_rgb.shape[1])
    return float(np.average(albedo_map.albedo_rgb[..., min(1, channels - 1)], weights=weights))


__all__ = [
    "EarthSurfaceModel",
    "build_albedo_map",
    "earth_albedo_map",
    "land_fraction",
    "map_mean_albedo",
]
