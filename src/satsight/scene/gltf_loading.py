"""Read a glTF 2.0 file (.gltf or .glb) into parts and materials
(``satsight.scene.loading.load_mesh`` describes what is read and how parts are named)."""

from __future__ import annotations

import base64
import json
import logging
import struct
import urllib.parse
from dataclasses import replace
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
from satsight.scene.textures import SurfaceTextures, open_texture_file

log = logging.getLogger(__name__)

_COMPRESSION = {
    "KHR_draco_mesh_compression": "Draco",
    "EXT_meshopt_compression": "meshopt",
    "KHR_meshopt_compression": "meshopt",
}


def gltf_json(path: Path) -> dict:
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


def refuse_compression(header: dict, path: Path) -> None:
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
        tuple(clip01(c) for c in rgba[:3]),
        clip01(metallic),
        clip01(roughness),
        float(ior) if ior >= 1.0 else 1.5,
        1.0 if alpha_mode == "OPAQUE" else clip01(rgba[3]),
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


def read_gltf(path: Path, header: dict, report: TextureReport):
    scene = load_trimesh_scene(path)
    refuse_empty(scene, path)
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
        surface = part_surface(mesh, textures.get(material_name), path, name)
        if surface is not None and surface.vertex_normals is not None:
            # Normals transform with the inverse transpose of the node's linear part.
            turned = surface.vertex_normals @ np.linalg.inv(transform[:3, :3])
            surface = replace(surface, vertex_normals=turned)
        parts.append((unique_name(name, taken), material_name, vertices, faces, surface))
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
    material, name: str, entry: dict | None, header: dict, path: Path, report: TextureReport
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
        images[key] = texture_image(image, encoding, wrap, path, report, name, label)
    for unread in ("emissiveTexture", "occlusionTexture"):
        if entry.get(unread):
            log.warning("%s: %s is not read", path.name, unread)
    if not any(v is not None for v in images.values()):
        return None
    scale = float((entry.get("normalTexture") or {}).get("scale", 1.0))
    return SurfaceTextures(**images, normal_scale=scale)
