"""Textures of procedural satellites: what real hardware shows at centimetre scale.

* **Solar cells** (``solar_cell_textures``): one tile per cell, repeated over the panel:
  the cell (the ``solar_cell`` material), the gaps between cells where the substrate
  shows, a silver busbar along one long edge and the thin silver contact fingers across
  the cell. The cell size is that of space triple-junction GaAs cells (the AZUR SPACE
  3G30C cell is 80 mm x 40 mm, 30.18 cm^2, manufacturer's datasheet); gap, busbar and
  finger sizes are assumed (0.9 mm, 1.5 mm, 0.1 mm). Each texel holds the average of the
  materials over its area (8 x 8 sub-samples), so features narrower than a texel keep
  their area fraction.
* **MLI crinkle** (``mli_crinkle_textures``): a tangent-space normal map of the wrinkles
  of multi-layer insulation: a periodic random height field (power-law spectrum of
  wavelengths between 1.5 and 15 cm, folded into ridges), its slopes scaled to an RMS
  tilt of ``MLI_RMS_TILT_DEG``. Periodic, so the tile repeats without seams; drawn from
  its own generator seeded by the satellite's seed, so a seed always gives the same
  wrinkles and the geometry's random draws are unchanged.
* **Radiator strips** (``radiator_textures``): white paint with strips of silvered tape
  (or second-surface mirrors) across the radiator.

Base colour and metallic-roughness tiles give the material values themselves
(``factors="replace"``); the part keeps its library material, which is the tile's main
surface. Values not taken from a cited source are assumptions, like the library's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from satsight.scene.materials import FIRST_MATERIALS, Material
from satsight.scene.mesh import TargetMesh
from satsight.scene.textures import SurfaceTextures, TextureImage, encode, normal_map_pixels

CELL_SIZE_M = (0.080, 0.040)  # (along the busbar, across it)
CELL_GAP_M = 0.0009
BUSBAR_WIDTH_M = 0.0015
FINGER_WIDTH_M = 0.0001
FINGER_PITCH_M = 0.0012
CELL_TILE_PX = (128, 64)
MLI_TILE_M = 0.6
MLI_TILE_PX = 256
MLI_RMS_TILT_DEG = 12.0
MLI_WAVELENGTHS_M = (0.015, 0.15)
RADIATOR_STRIP_PERIOD_M = 0.15
RADIATOR_STRIP_WIDTH_M = 0.025
_SUBSAMPLES = 8

_SILVER = Material("silver_contact", (0.90, 0.90, 0.88), 1.0, 0.30, 1.5)
_TAPE = Material("silver_tape", (0.92, 0.92, 0.90), 1.0, 0.20, 1.5)


def _material_tiles(
    labels: np.ndarray, materials: list[Material], weights: np.ndarray | None = None
) -> SurfaceTextures:
    """Base-colour and metallic-roughness tiles from a sub-sampled label image.

    labels: (H * s, W * s) index into ``materials`` per sub-sample (row 0 at the top).
    weights: optional (H * s, W * s, len(materials)) coverage per material instead.
    """
    s = _SUBSAMPLES
    if weights is None:
        weights = np.eye(len(materials))[labels]
    h, w = weights.shape[0] // s, weights.shape[1] // s
    cover = weights.reshape(h, s, w, s, -1).mean(axis=(1, 3))  # (H, W, materials)
    base = cover @ np.array([m.base_color_rgb for m in materials])
    metallic = cover @ np.array([m.metallic for m in materials])
    roughness = cover @ np.array([m.roughness for m in materials])
    mr = np.stack([np.zeros_like(metallic), roughness, metallic], axis=-1)
    return SurfaceTextures(
        base_color=TextureImage(encode(base, "srgb"), "srgb"),
        metallic_roughness=TextureImage(encode(mr, "linear"), "linear"),
        factors="replace",
    )


def cell_pitch_m(length_m: float, cell_m: float) -> float:
    """The cell pitch closest to ``cell_m`` that fits a whole number of cells in
    ``length_m``."""
    return length_m / max(1, round(length_m / cell_m))


def solar_cell_textures(
    pitch_uv_m: tuple[float, float], materials: Mapping[str, Material] = FIRST_MATERIALS
) -> SurfaceTextures:
    """The tile of one cell: u along the busbar over ``pitch_uv_m[0]``, v across it."""
    s = _SUBSAMPLES
    width, height = CELL_TILE_PX
    pu, pv = pitch_uv_m
    u = (np.arange(width * s) + 0.5) / (width * s) * pu  # metres from the tile's left edge
    v = (np.arange(height * s) + 0.5) / (height * s) * pv  # metres from its bottom edge
    uu, vv = np.meshgrid(u, v[::-1])  # row 0 at the top (v = pv)
    half_gap = 0.5 * CELL_GAP_M
    in_gap = (uu < half_gap) | (uu > pu - half_gap) | (vv < half_gap) | (vv > pv - half_gap)
    busbar = (vv >= half_gap) & (vv < half_gap + BUSBAR_WIDTH_M)
    finger = np.abs((uu - half_gap) % FINGER_PITCH_M - 0.5 * FINGER_PITCH_M) < 0.5 * FINGER_WIDTH_M
    labels = np.zeros(uu.shape, dtype=np.int64)  # 0 cell
    labels[finger | busbar] = 1  # silver
    labels[in_gap] = 2  # substrate between cells
    tiles = [materials["solar_cell"], _SILVER, materials["panel_substrate"]]
    return _material_tiles(labels, tiles)


def radiator_textures(materials: Mapping[str, Material] = FIRST_MATERIALS) -> SurfaceTextures:
    """One strip period along u: white paint, then a strip of silvered tape."""
    s = _SUBSAMPLES
    width, height = 64, 4
    u = (np.arange(width * s) + 0.5) / (width * s) * RADIATOR_STRIP_PERIOD_M
    uu = np.broadcast_to(u, (height * s, width * s))
    labels = (uu >= RADIATOR_STRIP_PERIOD_M - RADIATOR_STRIP_WIDTH_M).astype(np.int64)
    return _material_tiles(labels, [materials["white_paint"], _TAPE])


def mli_crinkle_textures(rng: np.random.Generator) -> SurfaceTextures:
    """A seeded, periodic normal map of MLI wrinkles over ``MLI_TILE_M`` (see the module
    docstring); ``rng`` is the texture's own generator."""
    n = MLI_TILE_PX
    k = np.fft.fftfreq(n, d=MLI_TILE_M / n)  # cycles per metre
    kx, ky = np.meshgrid(k, k)
    kr = np.hypot(kx, ky)
    band = (kr >= 1.0 / MLI_WAVELENGTHS_M[1]) & (kr <= 1.0 / MLI_WAVELENGTHS_M[0])
    amplitude = np.where(band, 1.0 / np.maximum(kr, 1e-9) ** 1.5, 0.0)
    phase = rng.uniform(0.0, 2.0 * math.pi, size=(n, n))
    field = np.fft.ifft2(amplitude * np.exp(1j * phase)).real
    field /= field.std()
    height = -np.abs(np.tanh(field))  # folds: sharp creases at the zero crossings
    texel_m = MLI_TILE_M / n
    du = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) / (2 * texel_m)
    dv = -(np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) / (2 * texel_m)  # v up
    slope = np.sqrt(np.mean(du**2 + dv**2))
    scale = math.tan(math.radians(MLI_RMS_TILT_DEG)) / slope
    normals = np.stack([-scale * du, -scale * dv, np.ones_like(du)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return SurfaceTextures(
        normal=TextureImage(normal_map_pixels(normals), "linear"), procedural="mli_crinkle"
    )


#: Seeded patterns by their ``SurfaceTextures.procedural`` name: generator -> textures.
RESEEDABLE = {"mli_crinkle": mli_crinkle_textures}


def reseedable_parts(mesh: TargetMesh) -> list[int]:
    """Indices of the parts whose textures a seeded pattern made (``RESEEDABLE``)."""
    return [
        k
        for k, textures in enumerate(mesh.part_textures)
        if textures is not None and textures.procedural in RESEEDABLE
    ]


def reseeded(mesh: TargetMesh, seed: int, parts: list[int] | None = None) -> TargetMesh:
    """``mesh`` with the textures of the ``reseedable_parts`` parts (those among ``parts``
    where given) made again, part k from ``np.random.default_rng([seed, k])`` (same
    pattern, other wrinkles); the others unchanged."""
    parts = [k for k in reseedable_parts(mesh) if parts is None or k in parts]
    if not parts:
        return mesh
    textures = list(mesh.part_textures)
    for k in parts:
        old = textures[k]
        remade = RESEEDABLE[old.procedural](np.random.default_rng([int(seed), k]))
        textures[k] = dataclasses.replace(
            remade, normal_scale=old.normal_scale, factors=old.factors
        )
    return dataclasses.replace(mesh, part_textures=tuple(textures))
