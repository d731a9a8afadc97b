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

Code. This module checks the request, dispatches on the file type and resolves materials;
``obj_loading`` and ``gltf_loading`` read the two formats, with the helpers they share in
``mesh_file_reading``.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from satsight.errors import SatsightError
from satsight.scene.gltf_loading import gltf_json, read_gltf, refuse_compression
from satsight.scene.materials import DEFAULT_MATERIAL_NAME, FIRST_MATERIALS, Material
from satsight.scene.mesh import TargetMesh, merge_parts
from satsight.scene.mesh_file_reading import TextureReport, unique_name
from satsight.scene.normals import DEFAULT_CREASE_ANGLE_DEG
from satsight.scene.obj_loading import read_obj

log = logging.getLogger(__name__)

SUPPORTED_SUFFIXES = (".obj", ".gltf", ".glb")


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
    report = TextureReport(path, bool(strict_textures))
    if suffix == ".obj":
        parts, file_materials = read_obj(path, report)
    else:
        header = gltf_json(path)
        refuse_compression(header, path)
        parts, file_materials = read_gltf(path, header, report)
    parts, resolved = _resolve_materials(
        parts, library, file_materials, path, dict(builtin_materials or {})
    )
    parts, resolved = _whitespace_free_names(parts, resolved)
    scaled = [(n, m, v * scale_m, f, surface) for n, m, v, f, surface in parts]
    crease = float(crease_angle_deg) if crease_angle_deg > 0 else None
    return merge_parts(scaled, materials=resolved, name=path.stem, crease_angle_deg=crease)


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
                final = unique_name(f"{name}_file", set(resolved) | set(file_materials))
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


def _whitespace_free_names(parts, materials: dict):
    """Replace white space in part and material names with '_' (kept unique), so every name
    survives the OBJ/MTL model written beside a dataset and tokenised tools."""

    def clean(name: str) -> str:
        return re.sub(r"\s+", "_", name.strip()) or "unnamed"

    used = {p[1] for p in parts}
    renamed: dict[str, str] = {}
    taken_materials = {name for name in materials if name not in used}
    for name in sorted(used):
        renamed[name] = unique_name(clean(name), taken_materials)
    resolved = {k: v for k, v in materials.items() if k not in used}
    for old, new in renamed.items():
        resolved[new] = materials[old] if new == old else replace(materials[old], name=new)
    taken_parts: set[str] = set()
    cleaned = [(unique_name(clean(n), taken_parts), renamed[m], *rest) for n, m, *rest in parts]
    return cleaned, resolved
