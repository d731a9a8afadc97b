"""Write a TargetMesh as Wavefront OBJ + MTL: one object per part, one material per part.

The OBJ has one ``o <part name>`` per part, followed by ``usemtl <material name>``, that
part's vertices (metres, body frame, 9 significant digits) and its triangles (1-based,
counter-clockwise seen from outside). The MTL next to it holds, per material used:

* ``Kd``: base colour (linear RGB); ``Ks``: specular reflectance at normal incidence
  (paper Eq. 18); ``Ns``: Phong exponent equivalent to the roughness, 2 / R^4 - 2
  (R^2 the GGX width taken as a Beckmann width), clipped to [0, 1000];
* ``Ni``: index of refraction; ``d``: opacity;
* ``Pm`` / ``Pr``: metallic and roughness, the PBR extension of the MTL format.

``satsight.scene.loading.load_mesh`` reads the file back to the same parts and materials.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from satsight.errors import SatsightError
from satsight.scene.materials import Material
from satsight.scene.mesh import TargetMesh

_HEADER = """\
# satsight target '{name}': {parts} parts, {vertices} vertices, {triangles} triangles
# units: metres
# frame: the target's body frame (for procedural satellites: origin at the bus centre,
#   +z telescope boresight, +y solar-wing axis, +x = y cross z)
# one object per part; triangles counter-clockwise seen from outside
"""


def phong_exponent(roughness: float) -> float:
    """MTL ``Ns`` for a perceptual roughness R: 2 / R^4 - 2, clipped to [0, 1000]."""
    alpha_sq = max(roughness, 1e-3) ** 4
    return float(np.clip(2.0 / alpha_sq - 2.0, 0.0, 1000.0))


def _check_name(kind: str, name: str) -> None:
    if not name or re.search(r"\s", name) or name != name.strip():
        raise SatsightError(
            f"cannot write {kind} name {name!r} to OBJ/MTL: names must be non-empty and "
            "contain no white space; rename it (e.g. with underscores)"
        )


def _mtl_entry(name: str, material: Material) -> str:
    kd = " ".join(f"{c:.6f}" for c in material.base_color_rgb)
    ks = " ".join(f"{c:.6f}" for c in material.ks_rgb)
    return (
        f"newmtl {name}\n"
        f"# source: {material.source}\n"
        f"Kd {kd}\nKs {ks}\nNs {phong_exponent(material.roughness):.4f}\n"
        f"Ni {material.ior:.6f}\nd {material.alpha:.6f}\n"
        f"Pm {material.metallic:.6f}\nPr {material.roughness:.6f}\nillum 2\n"
    )


def write_obj(mesh: TargetMesh, obj_path: str | Path) -> tuple[Path, Path]:
    """Write ``mesh`` to ``obj_path`` (.obj) and its materials to the .mtl beside it.

    Returns (obj path, mtl path). Vertices of each part are written once per part, so a
    vertex shared by two parts is duplicated; parts keep their order (part id = index + 1).
    """
    obj_path = Path(obj_path)
    if obj_path.suffix.lower() != ".obj":
        raise SatsightError(f"OBJ output path must end in .obj, got '{obj_path}'")
    if not obj_path.parent.is_dir():
        raise SatsightError(f"folder '{obj_path.parent}' does not exist; create it first")
    mtl_path = obj_path.with_suffix(".mtl")
    for name in mesh.part_names:
        _check_name("part", name)
    for name in mesh.part_materials:
        _check_name("material", name)

    title = " ".join(mesh.name.split())  # one line in the header comments
    out = io.StringIO()
    out.write(
        _HEADER.format(
            name=title,
            parts=len(mesh.part_names),
            vertices=len(mesh.vertices_m),
            triangles=len(mesh.faces),
        )
    )
    out.write(f"mtllib {mtl_path.name}\n")
    written = 0  # vertices written so far (OBJ indices are global and 1-based)
    for index, (name, material) in enumerate(
        zip(mesh.part_names, mesh.part_materials, strict=True)
    ):
        faces = mesh.faces[mesh.face_part_index == index]
        if len(faces) == 0:
            continue
        used, local = np.unique(faces, return_inverse=True)
        out.write(f"o {name}\nusemtl {material}\n")
        np.savetxt(out, mesh.vertices_m[used], fmt="v %.9g %.9g %.9g")
        np.savetxt(out, local.reshape(-1, 3) + written + 1, fmt="f %d %d %d")
        written += len(used)
    obj_path.write_text(out.getvalue(), encoding="utf-8")

    used_materials = dict.fromkeys(mesh.part_materials)
    entries = [_mtl_entry(name, mesh.materials[name]) for name in used_materials]
    mtl_header = f"# satsight materials of '{title}' (metallic/roughness PBR in Pm/Pr)\n"
    mtl_path.write_text(mtl_header + "\n".join(entries), encoding="utf-8")
    return obj_path, mtl_path
