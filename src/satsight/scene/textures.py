"""Surface textures of a target: 8-bit images that vary a part's material over its surface.

A part may carry a ``SurfaceTextures``: up to three images looked up at the hit's texture
coordinates (u, v), the per-corner ``TargetMesh.corner_uv`` interpolated with the hit's
barycentrics. They follow glTF 2.0's metallic-roughness material (Khronos, glTF 2.0
specification, section 3.9 "Materials"):

* ``base_color``: RGB, sRGB-encoded (decoded to linear reflectance with the sRGB
  transfer function, IEC 61966-2-1); multiplies the material's base colour.
* ``metallic_roughness``: linear; channel G multiplies the roughness, channel B the
  metallic factor (R is unused, as in glTF).
* ``normal``: a tangent-space normal map, linear, n = 2 * rgb - 1 with +x along +u,
  +y along +v and +z along the surface normal; x and y are scaled by ``normal_scale``
  (glTF ``normalTexture.scale``).

``factors="replace"`` makes the base-colour and metallic-roughness textures give the
parameters themselves (the material's own values then only describe the part's mean look,
e.g. for a model written to OBJ without its textures); procedural satellites use it for
their solar-cell grids and radiator strips. Loaded files always multiply (``"multiply"``).

Texture coordinates: u to the right, v *up*, (0, 0) the bottom-left corner of the image
(OpenGL's and trimesh's convention; glTF's top-left v is flipped on loading). Pixel row 0
of ``pixels`` is the image's top row. ``wrap_uv`` per axis: ``"repeat"`` (glTF's default),
``"clamp"`` (to the edge texel) or ``"mirror"`` (mirrored repeat).
"""

from __future__ import annotations

import io
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from satsight.errors import SatsightError

WRAP_MODES = ("repeat", "clamp", "mirror")
ENCODINGS = ("srgb", "linear")
FACTOR_MODES = ("multiply", "replace")
# Larger images are halved (2 x 2 box filter) on loading until they fit: a 8192^2 RGBA8
# texture already takes 256 MiB (341 MiB with its mip levels) in the renderer.
MAX_TEXTURE_SIDE_PX = 8192
#: Texture files with more pixels are not decoded (``open_texture_file``): memory. A file
#: at the limit (e.g. 16384 x 8192) takes about 3 GiB while it loads (0.5 GiB decoded,
#: as much again converted to RGB, 1.5 GiB as the float32 values it is halved in down to
#: ``MAX_TEXTURE_SIDE_PX``), for a texture the renderer keeps at 8192 x 4096 anyway. The
#: limit is below Pillow's own refusal (twice its ``MAX_IMAGE_PIXELS``, 179 Mpx), so every
#: file it passes opens.
MAX_TEXTURE_FILE_PIXELS = 2**27


@dataclass(frozen=True, eq=False)
class TextureImage:
    """One 8-bit image.

    pixels: (H, W, 3) uint8, row 0 the top of the image. encoding: ``"srgb"`` (colour)
    or ``"linear"`` (data: roughness, metallic, normals). wrap_uv: wrap mode along u and v.
    """

    pixels: np.ndarray
    encoding: str = "srgb"
    wrap_uv: tuple[str, str] = ("repeat", "repeat")

    def __post_init__(self) -> None:
        p = np.asarray(self.pixels)
        if p.ndim == 2:
            p = np.repeat(p[:, :, None], 3, axis=2)
        if p.ndim != 3 or p.shape[2] not in (3, 4) or min(p.shape[:2]) < 1:
            raise SatsightError(
                f"a texture must be an (H, W, 3) image, got an array of shape {p.shape}"
            )
        if p.dtype != np.uint8:
            raise SatsightError(f"texture pixels must be uint8 (8-bit), got {p.dtype}")
        p = np.ascontiguousarray(p[:, :, :3])
        while max(p.shape[:2]) > MAX_TEXTURE_SIDE_PX:
            p = halve(p, self.encoding)
        object.__setattr__(self, "pixels", p)
        wrap = tuple(self.wrap_uv)
        if self.encoding not in ENCODINGS:
            raise SatsightError(
                f"texture encoding must be one of {ENCODINGS}, got {self.encoding!r}"
            )
        if len(wrap) != 2 or any(w not in WRAP_MODES for w in wrap):
            raise SatsightError(f"texture wrap modes must be two of {WRAP_MODES}, got {wrap}")
        object.__setattr__(self, "wrap_uv", wrap)

    @property
    def size_px(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])


@dataclass(frozen=True, eq=False)
class SurfaceTextures:
    """The textures of one part (see the module docstring); any of them may be None.
    procedural: the name of the seeded pattern that made them, which can make them again
    from another generator (``satsight.scene.procedural_textures.RESEEDABLE``), or None."""

    base_color: TextureImage | None = None
    metallic_roughness: TextureImage | None = None
    normal: TextureImage | None = None
    normal_scale: float = 1.0
    factors: str = "multiply"
    procedural: str | None = None

    def __post_init__(self) -> None:
        if self.factors not in FACTOR_MODES:
            raise SatsightError(
                f"texture factors must be one of {FACTOR_MODES}, got {self.factors!r}"
            )
        if not np.isfinite(self.normal_scale):
            raise SatsightError(f"normal_scale must be finite, got {self.normal_scale}")
        if self.base_color is not None and self.base_color.encoding != "srgb":
            raise SatsightError("a base-colour texture is sRGB-encoded (glTF 2.0)")
        for name in ("metallic_roughness", "normal"):
            image = getattr(self, name)
            if image is not None and image.encoding != "linear":
                raise SatsightError(f"a {name} texture holds linear data, not sRGB")

    @property
    def empty(self) -> bool:
        return self.base_color is None and self.metallic_roughness is None and self.normal is None

    def without_colour(self) -> SurfaceTextures | None:
        """The normal map alone (for a part given a built-in material), or None."""
        if self.normal is None:
            return None
        return SurfaceTextures(
            normal=self.normal, normal_scale=self.normal_scale, procedural=self.procedural
        )


# --- encodings -------------------------------------------------------------------------------
def srgb_to_linear(encoded: np.ndarray) -> np.ndarray:
    """sRGB electro-optical transfer function (IEC 61966-2-1): encoded [0, 1] -> linear."""
    c = np.asarray(encoded, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Inverse of ``srgb_to_linear``: linear [0, 1] -> encoded [0, 1]."""
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1.0 / 2.4) - 0.055)


_CODES = np.arange(256) / 255.0
_SRGB_DECODED = srgb_to_linear(_CODES)  # linear value of each 8-bit sRGB code


def decode(pixels: np.ndarray, encoding: str, dtype=np.float64) -> np.ndarray:
    """uint8 pixels -> values in [0, 1] (linear light for ``"srgb"``)."""
    p = np.asarray(pixels, dtype=np.uint8)
    table = _SRGB_DECODED if encoding == "srgb" else _CODES
    return table.astype(dtype)[p]


def encode(values: np.ndarray, encoding: str) -> np.ndarray:
    """float values in [0, 1] (linear light for ``"srgb"``) -> uint8, rounded to the
    nearest code in the encoded scale."""
    x = np.clip(np.asarray(values, dtype=np.float32), 0.0, 1.0)
    if encoding == "srgb":
        x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, np.float32(1.0 / 2.4)) - 0.055)
    return np.round(x * 255.0).astype(np.uint8)


def _box_resample(x: np.ndarray, m: int, axis: int) -> np.ndarray:
    """Box-filter ``x`` along ``axis`` from n samples to m <= n / 2 (or m = 1): output k is
    the mean of the piecewise-constant input over [k n / m, (k + 1) n / m), each input
    sample weighted by its overlap; an interval shorter than 4 samples meets at most 4."""
    x = np.moveaxis(x, axis, 0)
    n = x.shape[0]
    if n == 2 * m:  # the usual case: pairs
        return np.moveaxis(0.5 * (x[0::2] + x[1::2]), 0, axis)
    if m == 1:
        return np.moveaxis(x.mean(axis=0, keepdims=True), 0, axis)
    ratio = n / m
    lo = np.arange(m) * ratio
    hi = lo + ratio
    first = np.floor(lo).astype(np.int64)
    out = np.zeros((m, *x.shape[1:]), dtype=x.dtype)
    for tap in range(4):
        i = first + tap
        weight = np.clip(np.minimum(hi, i + 1) - np.maximum(lo, i), 0.0, None) / ratio
        i = np.minimum(i, n - 1)
        out += x[i] * weight.astype(x.dtype)[(...,) + (None,) * (x.ndim - 1)]
    return np.moveaxis(out, 0, axis)


def halve_linear(values: np.ndarray) -> np.ndarray:
    """(H, W, C) linear values at half size (each side halved, rounded down, at least 1),
    by a box filter that covers every input texel (an odd side of 3 averages all three):
    the mean value is kept."""
    h, w = values.shape[:2]
    if h % 2 == 0 and w % 2 == 0:  # the usual case: 2 x 2 blocks in one pass
        return values.reshape(h // 2, 2, w // 2, 2, -1).mean(axis=(1, 3), dtype=values.dtype)
    values = _box_resample(values, max(1, h // 2), axis=0)
    return _box_resample(values, max(1, w // 2), axis=1)


def halve(pixels: np.ndarray, encoding: str) -> np.ndarray:
    """``halve_linear`` of uint8 pixels, decoded and re-encoded."""
    return encode(halve_linear(decode(pixels, encoding, np.float32)), encoding)


def normal_map_pixels(normals: np.ndarray) -> np.ndarray:
    """(H, W, 3) unit tangent-space normals -> uint8 normal-map pixels, (n + 1) / 2."""
    return encode(0.5 * (np.asarray(normals, dtype=np.float64) + 1.0), "linear")


# --- files -----------------------------------------------------------------------------------
def texture_size_problem(width: int, height: int) -> str | None:
    """Why an image of width x height pixels is not loaded as a texture, or None."""
    if width * height <= MAX_TEXTURE_FILE_PIXELS:
        return None
    return (
        f"is {width} x {height} px, more than the {MAX_TEXTURE_FILE_PIXELS:,} px "
        f"(2^27, e.g. 16384 x 8192) a texture file may hold (memory: a texture is "
        f"kept at {MAX_TEXTURE_SIDE_PX} px a side at most); scale it down"
    )


def open_texture_file(source: Path | bytes):
    """(image, None) for an image file or its bytes that may be used as a texture, opened
    lazily (only its header is read; ``numpy.asarray`` decodes it), else (None, why not):
    a missing file, one Pillow cannot read as an image, or one above
    ``MAX_TEXTURE_FILE_PIXELS``. Nothing is decoded to learn the size."""
    from PIL import Image

    if isinstance(source, Path):
        if not source.exists():
            return None, f"does not exist (looked for {source})"
        if not source.is_file():
            return None, f"is not a file ({source})"
    stream = io.BytesIO(source) if isinstance(source, bytes) else source
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our limit applies
        try:
            image = Image.open(stream)
        except Image.DecompressionBombError as error:
            count = re.search(r"\((\d+) pixels\)", str(error))
            pixels = f"{int(count.group(1)):,} px" if count else "too many pixels"
            return None, (
                f"holds {pixels}, more than the {MAX_TEXTURE_FILE_PIXELS:,} px (2^27) a "
                "texture file may hold (memory); scale it down"
            )
        except Exception as error:  # Pillow raises several types on what it cannot read
            return None, f"is not an image Pillow can read ({type(error).__name__}: {error})"
    problem = texture_size_problem(*image.size)
    if problem is not None:
        image.close()
        return None, problem
    return image, None
