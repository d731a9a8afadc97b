"""What the OBJ and glTF readers of ``satsight.scene.loading`` share: trimesh's scene of a
mesh file, each loaded part's surface (shading normals, texture coordinates, textures), the
conversion of a decoded texture image, and how an unusable texture is reported."""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np
import trimesh

from satsight.errors import SatsightError
from satsight.scene.mesh import PartSurface
from satsight.scene.textures import TextureImage, texture_size_problem

log = logging.getLogger(__name__)

STRICT_TEXTURES_KEY = "target.mesh.strict_textures"


class TextureReport:
    """Says that a texture of the mesh file ``path`` is not used: a WARNING (the material
    renders without it), or with ``strict`` a SatsightError."""

    def __init__(self, path: Path, strict: bool):
        self.path, self.strict = path, strict

    def problem(self, material: str, texture: str, why: str) -> None:
        where = f"{self.path.name}: material '{material}': texture {texture} {why}"
        if self.strict:
            raise SatsightError(
                f"{where}; fix the file or its reference ({STRICT_TEXTURES_KEY} is true; "
                "false renders the material without the texture, with a warning)"
            )
        log.warning(
            "%s; the material is rendered without it (%s: true makes this an error)",
            where,
            STRICT_TEXTURES_KEY,
        )


def load_trimesh_scene(path: Path, file_obj=None, **kwargs) -> trimesh.Scene:
    """trimesh's scene of ``path`` (or of ``file_obj``, the file's text as read here)."""
    from PIL import Image

    try:
        with warnings.catch_warnings():  # texture sizes are checked against our own limit
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            source = path if file_obj is None else file_obj
            return trimesh.load_scene(source, process=False, **kwargs)
    except Exception as error:  # trimesh raises many types on malformed input
        raise SatsightError(f"trimesh could not read '{path}': {error}") from error


def refuse_empty(scene: trimesh.Scene, path: Path) -> None:
    """Raise unless the scene holds at least one triangle."""
    geometry = list(scene.geometry.values())
    if any(isinstance(g, trimesh.Trimesh) and len(g.faces) > 0 for g in geometry):
        return
    if geometry:
        kinds = sorted({type(g).__name__ for g in geometry})
        raise SatsightError(
            f"'{path}' holds only points or lines ({', '.join(kinds)}), no triangles; "
            "satsight renders surfaces: export the model as a triangle mesh"
        )
    raise SatsightError(f"'{path}' holds no triangles; nothing to render")


def clip01(value: float) -> float:
    """``value`` clipped to [0, 1] (a colour channel or factor read from a file)."""
    return float(np.clip(value, 0.0, 1.0))


def unique_name(name: str, taken: set[str]) -> str:
    """``name``, else ``name_2``, ``name_3``, ...: the first not in ``taken`` (added to it)."""
    candidate, k = name, 2
    while candidate in taken:
        candidate, k = f"{name}_{k}", k + 1
    taken.add(candidate)
    return candidate


def _file_normals(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """The vertex normals the file gave (trimesh keeps them in its cache), else None:
    trimesh would compute smooth ones on request, which ignore the crease angle."""
    cache = getattr(getattr(mesh, "_cache", None), "cache", {})
    normals = cache.get("vertex_normals") if isinstance(cache, dict) else None
    if normals is None or np.shape(normals) != np.shape(mesh.vertices):
        return None
    return np.asarray(normals, dtype=np.float64)


def part_surface(mesh: trimesh.Trimesh, textures, path: Path, name: str) -> PartSurface | None:
    """Normals, texture coordinates and textures of one loaded part (None if it has none)."""
    normals = _file_normals(mesh)
    uv = getattr(mesh.visual, "uv", None)
    if uv is not None:
        uv = np.asarray(uv, dtype=np.float64)
        if uv.shape != (len(mesh.vertices), 2) or not np.all(np.isfinite(uv)):
            uv = None
    if textures is not None and textures.empty:
        textures = None
    if textures is not None and uv is None:
        log.warning(
            "%s: part '%s' has textures but no texture coordinates; not textured", path.name, name
        )
        textures = None
    if normals is None and uv is None:
        return None
    return PartSurface(vertex_normals=normals, vertex_uv=uv, textures=textures)


def texture_image(
    image, encoding: str, wrap_uv, path: Path, report: TextureReport, material: str, label: str
) -> TextureImage | None:
    """A TextureImage from a PIL image (8-bit RGB; 16-bit and float images are scaled),
    or None after ``report`` has said why not (too many pixels, or not decodable)."""
    problem = texture_size_problem(*image.size)  # from the header, before decoding
    if problem is not None:
        report.problem(material, label, problem)
        return None
    try:
        mode = getattr(image, "mode", "RGB")
        if mode.startswith("I") or mode == "F":  # 16/32-bit grey
            values = np.asarray(image, dtype=np.float64)
            top = 65535.0 if values.max(initial=0) > 255 else 255.0
            pixels = np.round(np.clip(values / top, 0, 1) * 255).astype(np.uint8)
        else:
            pixels = np.asarray(image.convert("RGB"), dtype=np.uint8)
        return TextureImage(pixels, encoding, wrap_uv)
    except (OSError, ValueError, SyntaxError, SatsightError) as error:
        report.problem(material, label, f"could not be decoded ({error})")
        return None
