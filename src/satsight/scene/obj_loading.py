"""Read a Wavefront OBJ file and its MTL material libraries into parts and materials
(``satsight.scene.loading.load_mesh`` describes what is read and how parts are named)."""

from __future__ import annotations

import io
import logging
import re
import warnings
from pathlib import Path

import numpy as np
import trimesh

from satsight.errors import SatsightError
from satsight.scene.materials import Material
from satsight.scene.mesh_file_reading import (
    TextureReport,
    clip01,
    load_trimesh_scene,
    part_surface,
    refuse_empty,
    texture_image,
    unique_name,
)
from satsight.scene.textures import SurfaceTextures, TextureImage, open_texture_file

log = logging.getLogger(__name__)

_OBJ_DIRECTIVE = re.compile(r"^(o|g|usemtl|f)[ \t]+(.*?)[ \t]*$", re.MULTILINE)


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


def read_obj(path: Path, report: TextureReport):
    text = path.read_text(encoding="utf-8", errors="replace")
    absolute = _obj_absolute_faces(text, path)
    options = {
        "split_objects": True,
        "split_groups": True,
        "group_material": True,
        "maintain_order": False,
    }
    if absolute is None:
        scene = load_trimesh_scene(path, **options)
    else:  # read from memory; materials and textures still resolve beside the file
        scene = load_trimesh_scene(
            path,
            file_obj=io.BytesIO(absolute.encode("utf-8")),
            file_type="obj",
            resolver=trimesh.resolvers.FilePathResolver(path),
            **options,
        )
    refuse_empty(scene, path)
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
        surface = part_surface(mesh, textures.get(material), path, name)
        parts.append((unique_name(name, taken), material, vertices, np.array(mesh.faces), surface))
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
    mtl: Path, number: int, name: str, path: Path, material: str, report: TextureReport
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
        return texture_image(image, "srgb", ("repeat", "repeat"), path, report, material, label)


def _log_unread_mtl_maps(mtl: Path, text: str) -> None:
    """Log the MTL texture maps satsight does not read (all but ``map_Kd``)."""
    keys = re.findall(r"^[ \t]*(map_\w+|bump|norm|disp|refl)[ \t]", text, re.M)
    unread = sorted({k for k in keys if k.lower() != "map_kd"})
    if unread:
        log.warning("%s: texture maps not read: %s", mtl.name, ", ".join(unread))


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
        tuple(clip01(c) for c in color),
        clip01(_mtl_scalar(values, "pm") or 0.0),
        clip01(0.5 if roughness is None else roughness),
        ior if ior is not None and ior >= 1.0 else 1.5,
        clip01(1.0 if alpha is None else alpha),
        source=f"{path.name}: MTL Kd/Pm/Pr/Ns/Ni/d (missing keys take loader defaults)",
    )
