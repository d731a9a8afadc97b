"""Load a target mesh from Wavefront OBJ (+ MTL) or glTF 2.0 (.gltf / .glb) through trimesh.

Parts. OBJ: one part per (object ``o``, group ``g``, material ``usemtl``) run of faces, in
order of first appearance, named ``<o>`` / ``<g>`` / ``<o>_<g>`` (``_<material>`` added only
where one object uses several materials). glTF: one part per node holding a mesh, named after
the node, in node order; a mesh of several primitives gives ``<node>_prim<k>`` parts. Node
transforms (the scene graph) are applied; mirroring transforms keep triangles outward.

Materials. A part's material name found in the library (``materials``, else
``FIRST_MATERIALS``) uses the library definition. Otherwise a ``Material`` of that name is
built from the file: glTF ``pbrMetallicRoughness`` base colour / metallic / roughness (glTF
defaults 1, 1, 1), opacity = base colour alpha unless ``alphaMode`` is OPAQUE, IOR from
``KHR_materials_ior`` (default 1.5); MTL ``Kd``, ``Pm`` (default 0), ``Pr`` (else from ``Ns``
as (2 / (Ns + 2))^(1/4), else 0.5), ``Ni`` (default 1.5), ``d`` (else 1 - ``Tr``, else 1).
A name with no definition anywhere gets the values of ``DEFAULT_MATERIAL_NAME``; faces with
no material at all use ``DEFAULT_MATERIAL_NAME`` itself. Each such fallback is logged.
Textures are ignored.

Units. glTF is in metres; OBJ has no unit and is read as metres. Both are multiplied by
``scale_m``.
"""

from __future__ import annotations

import json
import logging
import re
import struct
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
import trimesh

from satsight.errors import SatsightError
from satsight.scene.materials import DEFAULT_MATERIAL_NAME, FIRST_MATERIALS, Material
from satsight.scene.mesh import TargetMesh, merge_parts

log = logging.getLogger(__name__)

SUPPORTED_SUFFIXES = (".obj", ".gltf", ".glb")
_COMPRESSION = {
    "KHR_draco_mesh_compression": "Draco",
    "EXT_meshopt_compression": "meshopt",
    "KHR_meshopt_compression": "meshopt",
}
_OBJ_DIRECTIVE = re.compile(r"^(o|g|usemtl|f)[ \t]+(.*?)[ \t]*$", re.MULTILINE)


def load_mesh(
    path: str | Path, materials: Mapping[str, Material] | None = None, scale_m: float = 1.0
) -> TargetMesh:
    """Read an OBJ / glTF / GLB file into a TargetMesh (vertices in metres times ``scale_m``)."""
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
    library = dict(FIRST_MATERIALS if materials is None else materials)
    if suffix == ".obj":
        parts, file_materials = _read_obj(path)
    else:
        header = _gltf_json(path)
        _refuse_compression(header, path)
        parts, file_materials = _read_gltf(path, header)
    parts, resolved = _resolve_materials(parts, library, file_materials, path)
    parts, resolved = _whitespace_free_names(parts, resolved)
    scaled = [(n, m, v * scale_m, f) for n, m, v, f in parts]
    return merge_parts(scaled, materials=resolved, name=path.stem)


# --- shared -----------------------------------------------------------------------------------
def _resolve_materials(parts, library: dict, file_materials: dict, path: Path):
    """Parts with a material name each, and the definitions: library, file, then default."""
    resolved = dict(library)
    default = library.get(DEFAULT_MATERIAL_NAME, FIRST_MATERIALS[DEFAULT_MATERIAL_NAME])
    named, bare = [], []
    for part_name, material_name, vertices, faces in parts:
        if material_name is None:
            bare.append(part_name)
            material_name = DEFAULT_MATERIAL_NAME
            resolved.setdefault(material_name, default)
        elif material_name not in resolved and material_name in file_materials:
            resolved[material_name] = file_materials[material_name]
        elif material_name not in resolved:
            log.warning(
                "%s: material '%s' has no definition; using the values of '%s'",
                path.name,
                material_name,
                DEFAULT_MATERIAL_NAME,
            )
            source = f"assumed: no definition in {path.name}; values of {DEFAULT_MATERIAL_NAME}"
            resolved[material_name] = replace(default, name=material_name, source=source)
        named.append((part_name, material_name, vertices, faces))
    if bare:
        shown = ", ".join(bare[:5]) + (", ..." if len(bare) > 5 else "")
        log.warning(
            "%s: %d part(s) have no material (%s); using '%s'",
            path.name,
            len(bare),
            shown,
            DEFAULT_MATERIAL_NAME,
        )
    return named, resolved


def _load_scene(path: Path, **kwargs) -> trimesh.Scene:
    try:
        return trimesh.load_scene(path, process=False, **kwargs)
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

    used = {m for _, m, _, _ in parts}
    renamed: dict[str, str] = {}
    taken_materials = {name for name in materials if name not in used}
    for name in sorted(used):
        renamed[name] = _unique(clean(name), taken_materials)
    resolved = {k: v for k, v in materials.items() if k not in used}
    for old, new in renamed.items():
        resolved[new] = materials[old] if new == old else replace(materials[old], name=new)
    taken_parts: set[str] = set()
    cleaned = [(_unique(clean(n), taken_parts), renamed[m], v, f) for n, m, v, f in parts]
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


def _read_obj(path: Path):
    scene = _load_scene(
        path, split_objects=True, split_groups=True, group_material=True, maintain_order=False
    )
    _refuse_empty(scene, path)
    text = path.read_text(encoding="utf-8", errors="replace")
    for library_file in re.findall(r"^mtllib[ \t]+(.+?)[ \t]*$", text, flags=re.MULTILINE):
        if not (path.parent / library_file).is_file():
            log.warning("%s: material library '%s' not found", path.name, library_file)
    runs = _obj_runs(text)
    geometry = {k: g for k, g in scene.geometry.items() if isinstance(g, trimesh.Trimesh)}
    parts, file_materials, taken = [], {}, set()
    for name, material, mesh in _name_obj_parts(runs, geometry, path):
        if len(mesh.faces) == 0:
            continue
        vertices = np.array(mesh.vertices, dtype=float)
        parts.append((_unique(name, taken), material, vertices, np.array(mesh.faces)))
        parsed = getattr(mesh.visual, "material", None)  # trimesh's parse of the MTL entry
        if material is not None and parsed is not None and material not in file_materials:
            file_materials[material] = _mtl_material(material, parsed, path)
    return parts, file_materials


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


def _read_gltf(path: Path, header: dict):
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

    parts, file_materials, taken = [], {}, set()
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
        vertices = trimesh.transformations.transform_points(
            np.asarray(mesh.vertices, float), transform
        )
        faces = np.asarray(mesh.faces, dtype=np.int64)
        if np.linalg.det(transform[:3, :3]) < 0:
            faces = faces[:, ::-1]
        parts.append((_unique(name, taken), material_name, vertices, faces))
    return parts, file_materials
