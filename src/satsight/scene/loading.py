"""Load a target mesh from Wavefront OBJ (+ MTL) or glTF 2.0 (.gltf / .glb) through trimesh.

Parts. OBJ: one part per (object ``o``, group ``g``, material ``usemtl``) run of faces, in
order of first appearance, named ``<o>`` / ``<g>`` / ``<o>_<g>`` (``_<material>`` added only
where one object uses several materials). glTF: one part per node holding a mesh, named after
the node, in node order; a mesh of several primitives gives ``<node>_prim<k>`` parts. Node
transforms (the scene graph) are applied; mirroring transforms keep triangles outward.

Materials. A part's material comes from the file: glTF ``pbrMetallicRoughness`` base colour /
metallic / roughness (glTF defaults 1, 1, 1), opacity = base colour alpha unless
``alphaMode`` is OPAQUE, IOR from ``KHR_materials_ior`` (default 1.5); MTL ``Kd``, ``Pm``
(default 0), ``Pr`` (else from ``Ns`` as (2 / (Ns + 2))^(1/4), else 0.5), ``Ni`` (default
1.5), ``d`` (else 1 - ``Tr``, else 1). The file's values win even where a material's name
is that of a built-in material: a library material (``materials``, else
``FIRST_MATERIALS``) is used only where ``builtin_materials`` asks for it, by part name or
by the file's material name (the scenario's ``target.mesh.materials``). A name the file
does not define gets the values of ``DEFAULT_MATERIAL_NAME``; faces with no material at
all use ``DEFAULT_MATERIAL_NAME`` itself. Each choice is logged (INFO: which materials
come from the file and which are built-in; WARNING: every fallback).

Surfaces. Shading normals come from the file (OBJ ``vn``, glTF ``NORMAL``, turned by the
node transform's inverse transpose); parts without them get crease-angle normals
(``crease_angle_deg``, ``satsight.scene.normals``; 0 keeps triangles flat). Texture
coordinates (OBJ ``vt``, glTF ``TEXCOORD_0``) and textures load with them: glTF
``baseColorTexture``, ``metallicRoughnessTexture`` (G roughness, B metallic) and
``normalTexture`` (with its ``scale``), and their samplers' wrap modes; OBJ ``map_Kd``.
Textures multiply the material's factors (glTF 2.0 section 3.9; the MTL format's
``map_Kd`` multiplies ``Kd``). Not read: other texture coordinate sets, texture transforms
(``KHR_texture_transform``), emission, occlusion, OBJ bump and PBR maps (each logged when
present). A part given a built-in material keeps its normal map and drops its colour
textures.

Units. glTF is in metres; OBJ has no unit and is read as metres. Both are multiplied by
``scale_m``.
"""

from __future__ import annotations

import base64
import io
import json
import logging
import re
import struct
import urllib.parse
import warnings
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
import trimesh

from satsight.errors import SatsightError
from satsight.scene.materials import DEFAULT_MATERIAL_NAME, FIRST_MATERIALS, Material
from satsight.scene.mesh import PartSurface, TargetMesh, merge_parts
from satsight.scene.normals import DEFAULT_CREASE_ANGLE_DEG
from satsight.scene.textures import (
    SurfaceTextures,
    TextureImage,
    open_texture_file,
    texture_size_problem,
)

log = logging.getLogger(__name__)

SUPPORTED_SUFFIXES = (".obj", ".gltf", ".glb")
_COMPRESSION = {
    "KHR_draco_mesh_compression": "Draco",
    "EXT_meshopt_compression": "meshopt",
    "KHR_meshopt_compression": "meshopt",
}
STRICT_TEXTURES_KEY = "target.mesh.strict_textures"


class _TextureReport:
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


_OBJ_DIRECTIVE = re.compile(r"^(o|g|usemtl|f)[ \t]+(.*?)[ \t]*$", re.MULTILINE)


def load_mesh(
    path: str | Path,
    materials: Mapping[str, Material] | None = None,
    scale_m: float = 1.0,
    builtin_materials: Mapping[str, str] | None = None,
    crease_angle_deg: float = DEFAULT_CREASE_ANGLE_DEG,
    strict_textures: bool = False,
) -> TargetMesh:
    """Read an OBJ / glTF / GLB file into a TargetMesh (vertices in metres times ``scale_m``).

    materials: the library that ``builtin_materials`` picks from (default
    ``FIRST_MATERIALS``). builtin_materials: {part name or file material name: library
    material name}, the parts that take a library material instead of the file's (a part
    name wins over a material name). crease_angle_deg: smoothing angle for parts the file
    gives no normals (0: flat triangles). strict_textures: a texture the file names but
    that cannot be used (missing, not an image, above ``MAX_TEXTURE_FILE_PIXELS``) is an
    error instead of a warning (the material then renders without it).
    """
    path = Path(path)
    if not path.is_file():
        raise SatsightError(f"mesh file '{path}' does not exist (or is not a file)")
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise SatsightError(
            f"cannot load '{path.name}': unsupported file type '{suffix}'; supported: "
            f"{', '.join(SUPPORTED_SUFFIXES)} (convert other formats, e.g. with Blender)"
        )
    if not (np.isfinite(scale_m) and scale_m > 0):
        raise SatsightError(f"scale_m must be a positive number of metres, got {scale_m}")
    if not (np.isfinite(crease_angle_deg) and 0.0 <= crease_angle_deg <= 180.0):
        raise SatsightError(f"crease_angle_deg must be in [0, 180] degrees, got {crease_angle_deg}")
    library = dict(FIRST_MATERIALS if materials is None else materials)
    report = _TextureReport(path, bool(strict_textures))
    if suffix == ".obj":
        parts, file_materials = _read_obj(path, report)
    else:
        header = _gltf_json(path)
        _refuse_compression(header, path)
        parts, file_materials = _read_gltf(path, header, report)
    parts, resolved = _resolve_materials(
        parts, library, file_materials, path, dict(builtin_materials or {})
    )
    parts, resolved = _whitespace_free_names(parts, resolved)
    scaled = [(n, m, v * scale_m, f, surface) for n, m, v, f, surface in parts]
    crease = float(crease_angle_deg) if crease_angle_deg > 0 else None
    return merge_parts(scaled, materials=resolved, name=path.stem, crease_angle_deg=crease)


# --- shared -----------------------------------------------------------------------------------
def _check_builtin_request(parts, library: dict, builtin: dict, path: Path) -> None:
    """Refuse built-in requests that name no library material, or no part or material."""
    unknown = sorted({v for v in builtin.values() if v not in library})
    if unknown:
        raise SatsightError(
            f"target.mesh.materials asks for unknown built-in material(s) {', '.join(unknown)}; "
            f"known: {', '.join(sorted(library))}"
        )
    part_names = {p[0] for p in parts}
    material_names = {p[1] for p in parts if p[1] is not None}
    unused = sorted(set(builtin) - part_names - material_names)
    if unused:
        raise SatsightError(
            f"target.mesh.materials names {', '.join(repr(k) for k in unused)}, which is "
            f"neither a part nor a material of {path.name}; parts: "
            f"{', '.join(sorted(part_names))}; materials: {', '.join(sorted(material_names))}"
        )


def _resolve_materials(parts, library: dict, file_materials: dict, path: Path, builtin: dict):
    """Parts with a material name each, and their definitions: a built-in where
    ``builtin`` asks for one, else the file's, else the default's values (see the module
    docstring). A file material whose name is taken by a requested built-in is renamed
    ``<name>_file``."""
    _check_builtin_request(parts, library, builtin, path)
    default = library.get(DEFAULT_MATERIAL_NAME, FIRST_MATERIALS[DEFAULT_MATERIAL_NAME])
    choices = [builtin.get(p[0], builtin.get(p[1])) for p in parts]
    resolved: dict[str, Material] = {c: library[c] for c in choices if c is not None}
    if any(c is None and p[1] is None for c, p in zip(choices, parts, strict=True)):
        resolved.setdefault(DEFAULT_MATERIAL_NAME, default)
    renamed: dict[str, str] = {}  # file material name -> its name in the mesh

    def claim(name: str, material: Material) -> str:
        if name not in renamed:
            final = name
            if final in resolved:  # a built-in of this name is asked for elsewhere
                final = _unique(f"{name}_file", set(resolved) | set(file_materials))
                log.warning(
                    "%s: material '%s' of the file is renamed '%s' (the built-in '%s' is "
                    "asked for by target.mesh.materials)",
                    path.name,
                    name,
                    final,
                    name,
                )
            renamed[name] = final
            resolved[final] = material if final == name else replace(material, name=final)
        return renamed[name]

    named, bare, from_builtin, missing = [], [], [], []
    for choice, (part_name, material_name, vertices, faces, surface) in zip(
        choices, parts, strict=True
    ):
        if choice is not None:
            from_builtin.append(f"{part_name} ({material_name or 'no material'} -> {choice})")
            if surface is not None and surface.textures is not None:
                surface = replace(surface, textures=surface.textures.without_colour())
            named.append((part_name, choice, vertices, faces, surface))
            continue
        if material_name is None:
            bare.append(part_name)
            material_name = DEFAULT_MATERIAL_NAME
        elif material_name in file_materials:
            material_name = claim(material_name, file_materials[material_name])
        else:
            if material_name not in renamed:
                missing.append(material_name)
            source = f"assumed: no definition in {path.name}; values of {DEFAULT_MATERIAL_NAME}"
            material_name = claim(
                material_name, replace(default, name=material_name, source=source)
            )
        named.append((part_name, material_name, vertices, faces, surface))
    for name in missing:
        hint = ""
        if name in library:
            hint = (
                f" (a built-in material '{name}' exists; set target.mesh.materials: "
                f"{{{name}: {name}}} to use it)"
            )
        log.warning(
            "%s: material '%s' has no definition; using the values of '%s'%s",
            path.name,
            name,
            DEFAULT_MATERIAL_NAME,
            hint,
        )
    if bare:
        shown = ", ".join(bare[:5]) + (", ..." if len(bare) > 5 else "")
        log.warning(
            "%s: %d part(s) have no material (%s); using '%s'",
            path.name,
            len(bare),
            shown,
            DEFAULT_MATERIAL_NAME,
        )
    from_file = sorted(m for m, final in renamed.items() if m in file_materials)
    log.info(
        "%s: materials from the file: %s; built-in (target.mesh.materials): %s",
        path.name,
        ", ".join(from_file) or "none",
        ", ".join(from_builtin) or "none",
    )
    return named, resolved


def _load_scene(path: Path, file_obj=None, **kwargs) -> trimesh.Scene:
    """trimesh's scene of ``path`` (or of ``file_obj``, the file's text as read here)."""
    from PIL import Image

    try:
        with warnings.catch_warnings():  # texture sizes are checked against our own limit
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            source = path if file_obj is None else file_obj
            return trimesh.load_scene(source, process=False, **kwargs)
    except Exception as error:  # trimesh raises many types on malformed input
        raise SatsightError(f"trimesh could not read '{path}': {error}") from error


def _refuse_empty(scene: trimesh.Scene, path: Path) -> None:
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


def _clip01(value: float) -> float:
    return float(np.clip(value, 0.0, 1.0))


def _whitespace_free_names(parts, materials: dict):
    """Replace white space in part and material names with '_' (kept unique), so every name
    survives the OBJ/MTL model written beside a dataset and tokenised tools."""

    def clean(name: str) -> str:
        return re.sub(r"\s+", "_", name.strip()) or "unnamed"

    used = {p[1] for p in parts}
    renamed: dict[str, str] = {}
    taken_materials = {name for name in materials if name not in used}
    for name in sorted(used):
        renamed[name] = _unique(clean(name), taken_materials)
    resolved = {k: v for k, v in materials.items() if k not in used}
    for old, new in renamed.items():
        resolved[new] = materials[old] if new == old else replace(materials[old], name=new)
    taken_parts: set[str] = set()
    cleaned = [(_unique(clean(n), taken_parts), renamed[m], *rest) for n, m, *rest in parts]
    return cleaned, resolved


def _unique(name: str, taken: set[str]) -> str:
    candidate, k = name, 2
    while candidate in taken:
        candidate, k = f"{name}_{k}", k + 1
    taken.add(candidate)
    return candidate


# --- OBJ --------------------------------------------------------------------------------------
def _obj_runs(text: str) -> list[tuple[str | None, str | None, str | None]]:
    """(object, group, material) of each run of faces, in order of first appearance."""
    runs: dict[tuple, None] = {}
    state = {"o": None, "g": None, "usemtl": None}
    for match in _OBJ_DIRECTIVE.finditer(text):
        kind, value = match.groups()
        if kind == "f":
            runs.setdefault((state["o"], state["g"], state["usemtl"]), None)
        else:
            state[kind] = value
    return list(runs)


def _trimesh_obj_names(runs, file_name: str, with_material: bool) -> dict[str, tuple]:
    """The geometry name trimesh gives each run (split by object, group and material).

    trimesh joins object, group and, when the MTL defines more than one material, the
    material name with '_'; it names runs in reverse order, making repeats unique.
    """
    names: dict[str, tuple] = {}
    for obj, group, material in reversed(runs):
        pieces = [p for p in (obj, group) if p is not None]
        if with_material and material is not None:
            pieces.append(material)
        name = "_".join(pieces) if pieces else (obj or file_name)
        names[trimesh.util.unique_name(name, names)] = (obj, group, material)
    return names


def _name_obj_parts(runs, geometry: dict, path: Path) -> list[tuple]:
    """(part name, material name or None, trimesh mesh) per trimesh geometry, in file order."""
    run_of = {}
    for with_material in (True, False):
        candidate = _trimesh_obj_names(runs, path.name, with_material)
        if set(candidate) == set(geometry):
            run_of = candidate
            break
    if not run_of:
        log.warning(
            "%s: could not match trimesh's objects to the o/g/usemtl lines; parts keep "
            "trimesh's names and come after the matched ones",
            path.name,
        )
    bases = ["_".join(p for p in run[:2] if p is not None) or path.stem for run in runs]
    entries = []
    for key, mesh in geometry.items():
        run = run_of.get(key)
        if run is None:
            material = getattr(getattr(mesh.visual, "material", None), "name", None)
            entries.append(((len(runs), key), key, material, mesh))
            continue
        rank = runs.index(run)
        name, material = bases[rank], run[2]
        if bases.count(name) > 1 and material is not None:  # one object, several materials
            name = f"{name}_{material}"
        entries.append(((rank, key), name, material, mesh))
    entries.sort(key=lambda entry: entry[0])
    return [entry[1:] for entry in entries]


_OBJ_ELEMENT_LINE = re.compile(r"^[ \t]*(v|vt|vn)[ \t]", re.MULTILINE)
_OBJ_FACE_BODY = re.compile(r"^[ \t]*f[ \t]([^\n]*)", re.MULTILINE)
# What each field of a face corner ``v/vt/vn`` refers to, and the lines that define it.
_OBJ_SLOTS = (("v", "vertex"), ("vt", "texture coordinate"), ("vn", "normal"))
_PLURAL = {"vertex": "vertices", "texture coordinate": "texture coordinates", "normal": "normals"}


def _obj_absolute_faces(text: str, path: Path) -> str | None:
    """Check every face's indices; the text with relative indices made absolute where it
    has any (else None: trimesh can read the file as it is).

    OBJ counts vertices (``v``), texture coordinates (``vt``) and normals (``vn``) from 1;
    a negative index counts back from the last one defined *before* the face's line
    (-1: the latest). trimesh reads 0 as 1 and counts negative indices from the end of the
    file, so both are settled here: 0, and indices outside the file's elements, are an
    error naming the line; relative indices are rewritten as absolute ones.
    """
    bodies = " ".join(_OBJ_FACE_BODY.findall(text))
    if not bodies.strip():
        return None
    # Fast path, exact when it passes: every index is in 1..N, N a lower bound of the
    # smallest count of the elements the faces use (lines "v ", "vt ", "vn " at a line
    # start). Otherwise the exact count and the line-by-line check below.
    least = {key: text.startswith(key + " ") + text.count(f"\n{key} ") for key in ("v", "vt", "vn")}
    used = ["v"] + ["vt"] * bool(re.search(r"\d/\d", bodies))
    used += ["vn"] * bool(re.search(r"/\d*/\d", bodies))
    if "#" not in bodies and "-" not in bodies:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # numpy warns when it stops at a non-number
            try:
                values = np.fromstring(bodies.replace("/", " "), dtype=np.int64, sep=" ")
            except (ValueError, DeprecationWarning):
                values = np.zeros(0, dtype=np.int64)
        if values.size and values.min() >= 1 and values.max() <= min(least[k] for k in used):
            return None
    totals = dict.fromkeys(("v", "vt", "vn"), 0)
    for match in _OBJ_ELEMENT_LINE.finditer(text):
        totals[match.group(1)] += 1
    return _obj_faces_line_by_line(text, totals, path)


def _obj_faces_line_by_line(text: str, totals: dict[str, int], path: Path) -> str | None:
    """``_obj_absolute_faces``'s exact check, one line at a time."""
    seen = dict.fromkeys(totals, 0)
    lines = text.split("\n")
    rewritten = False
    for number, line in enumerate(lines, 1):
        stripped = line.lstrip()
        if stripped[:1] == "v":
            key = stripped.split(None, 1)[0]
            if key in seen:
                seen[key] += 1
            continue
        if stripped[:1] != "f" or stripped[1:2] not in (" ", "\t"):
            continue
        body = stripped[1:].partition("#")[0]
        corners = body.split()
        relative = False
        for c, corner in enumerate(corners):
            fields = corner.split("/")
            if len(fields) > 3:
                raise _face_error(path, number, line, f"corner '{corner}' has more than 3 fields")
            for f, ((key, noun), field) in enumerate(zip(_OBJ_SLOTS, fields, strict=False)):
                if not field:
                    if f == 0:
                        raise _face_error(path, number, line, f"corner '{corner}' has no vertex")
                    continue
                try:
                    index = int(field)
                except ValueError:
                    raise _face_error(
                        path, number, line, f"'{field}' in corner '{corner}' is not an integer"
                    ) from None
                if index == 0:
                    raise _face_error(
                        path,
                        number,
                        line,
                        f"{noun} index 0: OBJ indices start at 1 (1 is the first {noun}, "
                        f"-1 the latest one before this line); the exporter probably "
                        f"wrote 0-based indices: add 1 to every index",
                    )
                if index > totals[key]:
                    raise _face_error(
                        path,
                        number,
                        line,
                        f"{noun} index {index}, but the file defines {totals[key]} "
                        f"{_PLURAL[noun]} ('{key}' lines)",
                    )
                if index < 0:
                    if -index > seen[key]:
                        raise _face_error(
                            path,
                            number,
                            line,
                            f"relative {noun} index {index} reaches before the first "
                            f"{noun}: only {seen[key]} are defined above this line",
                        )
                    fields[f] = str(seen[key] + 1 + index)
                    relative = True
            corners[c] = "/".join(fields)
        if relative:
            indent = line[: len(line) - len(stripped)]
            lines[number - 1] = f"{indent}f {' '.join(corners)}"  # trimesh reads no comment
            rewritten = True
    return "\n".join(lines) if rewritten else None


def _face_error(path: Path, number: int, line: str, problem: str) -> SatsightError:
    shown = line.strip()
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    return SatsightError(f"{path.name}, line {number} ('{shown}'): {problem}")


def _read_obj(path: Path, report: _TextureReport):
    text = path.read_text(encoding="utf-8", errors="replace")
    absolute = _obj_absolute_faces(text, path)
    options = {
        "split_objects": True,
        "split_groups": True,
        "group_material": True,
        "maintain_order": False,
    }
    if absolute is None:
        scene = _load_scene(path, **options)
    else:  # read from memory; materials and textures still resolve beside the file
        scene = _load_scene(
            path,
            file_obj=io.BytesIO(absolute.encode("utf-8")),
            file_type="obj",
            resolver=trimesh.resolvers.FilePathResolver(path),
            **options,
        )
    _refuse_empty(scene, path)
    defined: set[str] = set()  # names of the materials the MTL files define
    colour_maps: dict[str, tuple[Path, int, str]] = {}  # material -> its map_Kd line
    for library_file in re.findall(r"^mtllib[ \t]+(.+?)[ \t]*$", text, flags=re.MULTILINE):
        mtl = path.parent / library_file
        if not mtl.is_file():
            log.warning("%s: material library '%s' not found", path.name, library_file)
            continue
        mtl_text = mtl.read_text(encoding="utf-8", errors="replace")
        defined |= set(re.findall(r"^[ \t]*newmtl[ \t]+(.+?)[ \t]*$", mtl_text, re.M))
        _log_unread_mtl_maps(mtl, mtl_text)
        for material, entry in _mtl_colour_maps(mtl, mtl_text).items():
            colour_maps.setdefault(material, entry)
    runs = _obj_runs(text)
    geometry = {k: g for k, g in scene.geometry.items() if isinstance(g, trimesh.Trimesh)}
    parts, file_materials, textures, taken = [], {}, {}, set()
    for name, material, mesh in _name_obj_parts(runs, geometry, path):
        if len(mesh.faces) == 0:
            continue
        vertices = np.array(mesh.vertices, dtype=float)
        # trimesh's parse of the MTL entry (it makes one up for names the MTL lacks).
        parsed = getattr(mesh.visual, "material", None) if material in defined else None
        if material is not None and parsed is not None and material not in file_materials:
            file_materials[material] = _mtl_material(material, parsed, path)
            if material in colour_maps:
                image = _map_kd_image(*colour_maps[material], path, material, report)
                textures[material] = SurfaceTextures(base_color=image)
        surface = _part_surface(mesh, textures.get(material), path, name)
        parts.append((_unique(name, taken), material, vertices, np.array(mesh.faces), surface))
    return parts, file_materials


# Options of an MTL texture map and how many values each takes (-o, -s, -t: 1 to 3).
_MAP_OPTIONS = {
    **dict.fromkeys(("-blendu", "-blendv", "-bm", "-boost", "-cc", "-clamp"), 1),
    **dict.fromkeys(("-imfchan", "-texres", "-type"), 1),
    "-mm": 2,
    **dict.fromkeys(("-o", "-s", "-t"), 3),
}


def _mtl_colour_maps(mtl: Path, text: str) -> dict[str, tuple[Path, int, str]]:
    """{material: (MTL file, line number, file name)} of each ``map_Kd`` line, its options
    (``-s 1 1 1`` and the like, not applied) taken off the file name."""
    maps: dict[str, tuple[Path, int, str]] = {}
    material = None
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split()
        if len(words) >= 2 and words[0] == "newmtl":
            material = line.split(None, 1)[1].strip()
        elif len(words) >= 2 and words[0].lower() == "map_kd" and material is not None:
            words = words[1:]
            options = []
            while len(words) > 1 and words[0].lower() in _MAP_OPTIONS:
                most = _MAP_OPTIONS[words[0].lower()]
                taken = 1
                while taken <= most and len(words) > taken + 1:
                    if most == 3 and not re.fullmatch(r"[-+]?[\d.eE+-]+", words[taken]):
                        break  # -o/-s/-t take 1 to 3 numbers
                    taken += 1
                options.append(" ".join(words[:taken]))
                words = words[taken:]
            if options:
                log.warning(
                    "%s, line %d: map_Kd options not applied: %s",
                    mtl.name,
                    number,
                    ", ".join(options),
                )
            maps.setdefault(material, (mtl, number, " ".join(words)))
    return maps


def _map_kd_image(
    mtl: Path, number: int, name: str, path: Path, material: str, report: _TextureReport
) -> TextureImage | None:
    """The ``map_Kd`` image of ``material`` (beside the MTL file, else beside the OBJ), or
    None after ``report`` has said why not."""
    candidates = [mtl.parent / name, path.parent / name]
    if "\\" in name:  # written on Windows
        candidates += [c.parent / name.replace("\\", "/") for c in candidates]
    file = next((c for c in candidates if c.is_file()), candidates[0])
    image, problem = open_texture_file(file)
    label = f"map_Kd '{name}' ({mtl.name} line {number})"
    if problem is not None:
        report.problem(material, label, problem)
        return None
    with image:  # closes the file, also when decoding fails
        return _texture_image(image, "srgb", ("repeat", "repeat"), path, report, material, label)


def _log_unread_mtl_maps(mtl: Path, text: str) -> None:
    """Log the MTL texture maps satsight does not read (all but ``map_Kd``)."""
    keys = re.findall(r"^[ \t]*(map_\w+|bump|norm|disp|refl)[ \t]", text, re.M)
    unread = sorted({k for k in keys if k.lower() != "map_kd"})
    if unread:
        log.warning("%s: texture maps not read: %s", mtl.name, ", ".join(unread))


def _file_normals(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """The vertex normals the file gave (trimesh keeps them in its cache), else None:
    trimesh would compute smooth ones on request, which ignore the crease angle."""
    cache = getattr(getattr(mesh, "_cache", None), "cache", {})
    normals = cache.get("vertex_normals") if isinstance(cache, dict) else None
    if normals is None or np.shape(normals) != np.shape(mesh.vertices):
        return None
    return np.asarray(normals, dtype=np.float64)


def _part_surface(mesh: trimesh.Trimesh, textures, path: Path, name: str) -> PartSurface | None:
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


def _texture_image(
    image, encoding: str, wrap_uv, path: Path, report: _TextureReport, material: str, label: str
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


def _mtl_scalar(values: dict, key: str) -> float | None:
    value = values.get(key)
    if isinstance(value, (list, tuple)):
        value = value[0] if value else None
    try:
        return None if value is None else float(value)
    except ValueError:
        return None


def _mtl_material(name: str, material, path: Path) -> Material:
    """A Material from trimesh's parse of an MTL entry (SimpleMaterial: keys in ``kwargs``)."""
    values = {k.lower(): v for k, v in getattr(material, "kwargs", {}).items()}
    kd = values.get("kd")
    color = np.resize(np.asarray(kd, dtype=float), 3) if kd is not None else np.full(3, 0.8)
    roughness = _mtl_scalar(values, "pr")
    ns = _mtl_scalar(values, "ns")
    if roughness is None and ns is not None:
        roughness = (2.0 / (max(ns, 0.0) + 2.0)) ** 0.25
    ior = _mtl_scalar(values, "ni")
    alpha = _mtl_scalar(values, "d")
    transparency = _mtl_scalar(values, "tr")
    if alpha is None and transparency is not None:
        alpha = 1.0 - transparency
    return Material(
        name,
        tuple(_clip01(c) for c in color),
        _clip01(_mtl_scalar(values, "pm") or 0.0),
        _clip01(0.5 if roughness is None else roughness),
        ior if ior is not None and ior >= 1.0 else 1.5,
        _clip01(1.0 if alpha is None else alpha),
        source=f"{path.name}: MTL Kd/Pm/Pr/Ns/Ni/d (missing keys take loader defaults)",
    )


# --- glTF -------------------------------------------------------------------------------------
def _gltf_json(path: Path) -> dict:
    """The JSON of a .gltf file or of the first (JSON) chunk of a .glb file."""
    try:
        if path.suffix.lower() == ".gltf":
            return json.loads(path.read_text(encoding="utf-8"))
        with path.open("rb") as stream:
            head = stream.read(20)
            if len(head) < 20 or head[:4] != b"glTF":
                raise SatsightError(f"'{path}' is not a binary glTF file (no 'glTF' magic)")
            _, version, _ = struct.unpack("<4sII", head[:12])
            length, kind = struct.unpack("<I4s", head[12:20])
            if version != 2 or kind != b"JSON":
                raise SatsightError(f"'{path}' is not a glTF 2.0 GLB (version {version})")
            return json.loads(stream.read(length).decode("utf-8"))
    except (ValueError, UnicodeDecodeError) as error:
        raise SatsightError(f"'{path}' has a broken glTF JSON part: {error}") from error


def _refuse_compression(header: dict, path: Path) -> None:
    declared = set(header.get("extensionsRequired", [])) | set(header.get("extensionsUsed", []))
    for mesh in header.get("meshes", []):
        for primitive in mesh.get("primitives", []):
            declared |= set(primitive.get("extensions", {}))
    for extension, label in _COMPRESSION.items():
        if extension in declared:
            raise SatsightError(
                f"'{path.name}' uses {label} mesh compression ({extension}), which satsight "
                "cannot decode; re-export the model without mesh compression (e.g. Blender's "
                "glTF exporter with Compression off) and load that file"
            )


def _gltf_material(name: str, material, entry: dict | None, path: Path) -> Material:
    """A Material from the glTF JSON ``entry`` (exact) or else trimesh's parsed material."""
    if entry is not None:
        pbr = entry.get("pbrMetallicRoughness", {})
        rgba = np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), dtype=float)
        metallic, roughness = pbr.get("metallicFactor", 1.0), pbr.get("roughnessFactor", 1.0)
        alpha_mode = entry.get("alphaMode", "OPAQUE")
        ior = entry.get("extensions", {}).get("KHR_materials_ior", {}).get("ior", 1.5)
    else:  # trimesh's PBRMaterial: colour as uint8 RGBA, None where the file gives nothing
        color = getattr(material, "baseColorFactor", None)
        rgba = np.ones(4) if color is None else np.asarray(color, dtype=float) / 255.0
        metallic = getattr(material, "metallicFactor", None)
        roughness = getattr(material, "roughnessFactor", None)
        metallic, roughness = (1.0 if v is None else v for v in (metallic, roughness))
        alpha_mode = getattr(material, "alphaMode", None) or "OPAQUE"
        ior = 1.5
    return Material(
        name,
        tuple(_clip01(c) for c in rgba[:3]),
        _clip01(metallic),
        _clip01(roughness),
        float(ior) if ior >= 1.0 else 1.5,
        1.0 if alpha_mode == "OPAQUE" else _clip01(rgba[3]),
        source=f"{path.name}: glTF pbrMetallicRoughness",
    )


def _gltf_frames(header: dict) -> dict[str, tuple[int, str]]:
    """trimesh's frame name of each glTF node -> (node index, part name).

    trimesh names a node's frame after the node (its index when unnamed), made unique as
    trimesh does; the part takes the node name, else its mesh name, else ``node_<index>``.
    """
    frames: dict[str, tuple[int, str]] = {}
    counts: dict = {}
    meshes = header.get("meshes", [])
    for index, node in enumerate(header.get("nodes", [])):
        frame = trimesh.util.unique_name(node.get("name", str(index)), frames, counts=counts)
        mesh = meshes[node["mesh"]] if isinstance(node.get("mesh"), int) else {}
        frames[frame] = (index, node.get("name") or mesh.get("name") or f"node_{index}")
    return frames


def _read_gltf(path: Path, header: dict, report: _TextureReport):
    scene = _load_scene(path)
    _refuse_empty(scene, path)
    frames = _gltf_frames(header)
    json_materials: dict[str, list[dict]] = {}
    for entry in header.get("materials", []):
        json_materials.setdefault(entry.get("name"), []).append(entry)
    geometry_rank = {name: k for k, name in enumerate(scene.geometry)}
    parents = scene.graph.transforms.parents

    entries = []
    for frame in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[frame]
        mesh = scene.geometry[geometry_name]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        if frame in frames:
            key = (*frames[frame], 0)
        else:  # trimesh hangs each primitive of a multi-primitive mesh on a random child name
            parent = parents.get(frame, frame)
            key = (*frames.get(parent, (len(frames), parent)), 1 + geometry_rank[geometry_name])
        entries.append((key, transform, mesh))
    entries.sort(key=lambda e: e[0])

    parts, file_materials, textures, taken = [], {}, {}, set()
    unnamed: dict[int, str] = {}
    primitives_seen: dict[tuple[int, str], int] = {}
    for (index, owner, primitive), transform, mesh in entries:
        name = owner
        if primitive:  # k-th primitive of this node, in the mesh's primitive order
            k = primitives_seen[index, owner] = primitives_seen.get((index, owner), -1) + 1
            name = f"{owner}_prim{k}"
        material = getattr(mesh.visual, "material", None)
        material_name = None
        if material is not None:
            material_name = material.name or unnamed.setdefault(
                id(material), f"{path.stem}_material_{len(unnamed)}"
            )
            if material_name not in file_materials:
                matches = json_materials.get(material.name, [])
                entry = matches[0] if len(matches) == 1 else None
                file_materials[material_name] = _gltf_material(material_name, material, entry, path)
                textures[material_name] = _gltf_textures(
                    material, material_name, entry, header, path, report
                )
        vertices = trimesh.transformations.transform_points(
            np.asarray(mesh.vertices, float), transform
        )
        faces = np.asarray(mesh.faces, dtype=np.int64)
        if np.linalg.det(transform[:3, :3]) < 0:
            faces = faces[:, ::-1]
        surface = _part_surface(mesh, textures.get(material_name), path, name)
        if surface is not None and surface.vertex_normals is not None:
            # Normals transform with the inverse transpose of the node's linear part.
            turned = surface.vertex_normals @ np.linalg.inv(transform[:3, :3])
            surface = replace(surface, vertex_normals=turned)
        parts.append((_unique(name, taken), material_name, vertices, faces, surface))
    return parts, file_materials


_GLTF_WRAP = {10497: "repeat", 33071: "clamp", 33648: "mirror"}


def _gltf_texture_info(header: dict, info: dict | None, path: Path, slot: str):
    """(wrap_uv) of a material's texture reference ``info``, logging what is not read."""
    if not info:
        return ("repeat", "repeat")
    if info.get("texCoord", 0) != 0:
        log.warning(
            "%s: %s uses TEXCOORD_%s; satsight reads TEXCOORD_0 only",
            path.name,
            slot,
            info.get("texCoord"),
        )
    if "KHR_texture_transform" in info.get("extensions", {}):
        log.warning("%s: %s has a KHR_texture_transform, which is not applied", path.name, slot)
    textures = header.get("textures", [])
    index = info.get("index")
    texture = textures[index] if isinstance(index, int) and 0 <= index < len(textures) else {}
    samplers = header.get("samplers", [])
    sampler_index = texture.get("sampler")
    sampler = (
        samplers[sampler_index]
        if isinstance(sampler_index, int) and 0 <= sampler_index < len(samplers)
        else {}
    )
    return (
        _GLTF_WRAP.get(sampler.get("wrapS", 10497), "repeat"),
        _GLTF_WRAP.get(sampler.get("wrapT", 10497), "repeat"),
    )


def _gltf_image_entry(header: dict, info: dict | None) -> tuple[int | None, dict]:
    """(index, entry) of the image a material's texture reference ``info`` names."""
    textures, images = header.get("textures", []), header.get("images", [])
    index = (info or {}).get("index")
    texture = textures[index] if isinstance(index, int) and 0 <= index < len(textures) else {}
    source = texture.get("source")
    if isinstance(source, int) and 0 <= source < len(images):
        return source, images[source]
    return None, {}


def _gltf_image_label(header: dict, info: dict | None) -> str:
    index, image = _gltf_image_entry(header, info)
    if index is None:
        return "no image"
    uri = image.get("uri", "")
    if uri and not uri.startswith("data:"):
        return f"'{uri}'"
    name = f" '{image['name']}'" if image.get("name") else ""
    return f"image {index}{name}, embedded"


def _gltf_uri_bytes(uri: str, path: Path) -> bytes | str:
    """The bytes a glTF URI names (data: URI or a file beside ``path``), or why not."""
    if uri.startswith("data:"):
        try:
            return base64.b64decode(uri.split(",", 1)[1])
        except (IndexError, ValueError) as error:
            return f"has a broken data URI ({error})"
    file = path.parent / urllib.parse.unquote(uri)
    if not file.is_file():
        return f"does not exist (looked for {file})"
    return file.read_bytes()


def _gltf_image_problem(header: dict, info: dict | None, path: Path) -> str:
    """Why the image of texture reference ``info`` could not be opened, read from the
    file's own description of it (header only: nothing is decoded)."""
    index, image = _gltf_image_entry(header, info)
    if index is None:
        return "names no image (textures[].source is missing or out of range)"
    data: bytes | str
    if "uri" in image:
        data = _gltf_uri_bytes(image["uri"], path)
    else:
        views, buffers = header.get("bufferViews", []), header.get("buffers", [])
        view_index = image.get("bufferView")
        if not (isinstance(view_index, int) and 0 <= view_index < len(views)):
            return "has neither a URI nor a valid bufferView"
        view = views[view_index]
        buffer = buffers[view.get("buffer", 0)] if buffers else {}
        if "uri" in buffer:
            data = _gltf_uri_bytes(buffer["uri"], path)
        else:
            data = _glb_binary_chunk(path)
        if isinstance(data, bytes):
            start = view.get("byteOffset", 0)
            data = data[start : start + view.get("byteLength", 0)]
    if isinstance(data, str):
        return data
    _, problem = open_texture_file(data)
    return problem or "could not be decoded"


def _glb_binary_chunk(path: Path) -> bytes | str:
    """The BIN chunk of a GLB file (glTF 2.0 section 4.4), or why there is none."""
    blob = path.read_bytes()
    json_length = struct.unpack_from("<I", blob, 12)[0] if len(blob) >= 16 else 0
    start = 20 + json_length
    if len(blob) < start + 8:
        return "lies in a binary chunk the file lacks"
    length, kind = struct.unpack_from("<I4s", blob, start)
    if kind != b"BIN\0":
        return "lies in a binary chunk the file lacks"
    return blob[start + 8 : start + 8 + length]


def _gltf_textures(
    material, name: str, entry: dict | None, header: dict, path: Path, report: _TextureReport
) -> SurfaceTextures | None:
    """The base-colour, metallic-roughness and normal textures of a glTF material (the
    images as trimesh decoded them; wrap modes and the normal scale from the JSON)."""
    entry = entry or {}
    pbr = entry.get("pbrMetallicRoughness", {})
    slots = {
        "base_color": ("baseColorTexture", pbr.get("baseColorTexture"), "srgb"),
        "metallic_roughness": (
            "metallicRoughnessTexture",
            pbr.get("metallicRoughnessTexture"),
            "linear",
        ),
        "normal": ("normalTexture", entry.get("normalTexture"), "linear"),
    }
    images = {}
    for key, (attribute, info, encoding) in slots.items():
        image = getattr(material, attribute, None)
        if not info and image is None:
            continue
        label = f"{attribute} ({_gltf_image_label(header, info)})"
        if image is None:  # trimesh could not open it: say why
            report.problem(name, label, _gltf_image_problem(header, info, path))
            continue
        wrap = _gltf_texture_info(header, info, path, attribute)
        images[key] = _texture_image(image, encoding, wrap, path, report, name, label)
    for unread in ("emissiveTexture", "occlusionTexture"):
        if entry.get(unread):
            log.warning("%s: %s is not read", path.name, unread)
    if not any(v is not None for v in images.values()):
        return None
    scale = float((entry.get("normalTexture") or {}).get("scale", 1.0))
    return SurfaceTextures(**images, normal_scale=scale)
