"""The target section of a scenario: a procedural satellite or a mesh file, and the
keypoints its labels carry."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from satsight.constants import DEFAULT_BAND_NM
from satsight.scene.band_reflectance import library_materials
from satsight.scene.keypoints import (
    DEFAULT_KEYPOINT_COUNT,
    KeypointRule,
    read_keypoints_file,
)
from satsight.scene.material_library import LIBRARY_PREFIX, list_materials
from satsight.scene.materials import FIRST_MATERIALS
from satsight.scene.mesh import TargetMesh
from satsight.scene.procedural_cache import satellite
from satsight.scene.satellite_classes import REPLICA_CLASSES, SATELLITE_CLASSES


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class KeypointsConfig(_Strict):
    """The keypoints labelled in every frame (``satsight.scene.keypoints``).

    method: ``surface`` (``count`` points spread over the mesh by farthest-point
    sampling), ``corners`` (the bounding box's 8 corners and centre) or ``file`` (the
    points in ``path``: body frame, metres; JSON list of [x, y, z] or text with x y z per
    line).
    """

    method: Literal["surface", "corners", "file"] = "surface"
    count: int = Field(default=DEFAULT_KEYPOINT_COUNT, ge=1, le=10000)
    path: Path | None = None

    @model_validator(mode="after")
    def _path_with_file(self) -> KeypointsConfig:
        if (self.method == "file") != (self.path is not None):
            raise ValueError("give 'path' exactly when method is 'file'")
        return self

    def build(self) -> KeypointRule:
        """The keypoint rule (the file's points read now)."""
        if self.method == "file":
            return KeypointRule("file", points_body_m=read_keypoints_file(self.path))
        return KeypointRule(self.method, self.count)


class ProceduralTargetConfig(_Strict):
    """A procedural satellite (``satsight.scene.procedural``) or a replica of a real one
    (``satsight.scene.replicas``: icesat2, oco2, galaxy19, cloudsat, jason2, tango): class,
    seed and surfaces.

    smooth_normals: crease-angle shading normals on curved parts (dish, cylinders).
    textures: solar-cell grids, MLI crinkle and radiator strips.
    materials: ``library`` (default: the spectral library's materials for the scenario's
    band, ``band_reflectance.BUILTIN_LIBRARY_MATCH``) or ``builtin`` (the typed built-in
    values; procedural classes only, the replicas' parts are library materials).
    """

    satellite_class: str = "two_wings"
    seed: int = Field(default=0, ge=0)
    smooth_normals: bool = True
    textures: bool = True
    materials: Literal["builtin", "library"] = "library"

    @model_validator(mode="after")
    def _known_class(self) -> ProceduralTargetConfig:
        if self.satellite_class not in SATELLITE_CLASSES + REPLICA_CLASSES:
            raise ValueError(
                f"unknown satellite_class '{self.satellite_class}'; choose one of "
                f"{', '.join(SATELLITE_CLASSES)} or a replica: {', '.join(REPLICA_CLASSES)}"
            )
        if self.satellite_class in REPLICA_CLASSES and self.materials == "builtin":
            raise ValueError(
                f"the replica '{self.satellite_class}' has spectral-library materials only; "
                "remove 'materials: builtin' (or set 'materials: library')"
            )
        return self


class MeshTargetConfig(_Strict):
    """A mesh file (``satsight.scene.loading.load_mesh``).

    materials: {part name or the file's material name: built-in material name, or
    ``library:NAME`` for a material of the spectral library (``satsight materials``), its
    colour integrated over the scenario's band}; those parts take that material instead of
    the file's values (which otherwise win, even where a file material is named like a
    built-in one). crease_angle_deg: parts the file gives no normals are smoothed across
    edges flatter than this (0: flat triangles). strict_textures: a texture the file names
    that is missing, not an image or too large (``MAX_TEXTURE_FILE_PIXELS``) stops the run
    with an error instead of a warning (its material then renders untextured).
    """

    path: Path
    scale_m: float = Field(default=1.0, gt=0, description="metres per file unit")
    materials: dict[str, str] = Field(default_factory=dict)
    crease_angle_deg: float = Field(default=30.0, ge=0.0, le=180.0)
    strict_textures: bool = False

    @field_validator("materials")
    @classmethod
    def _known_builtins(cls, value: dict[str, str]) -> dict[str, str]:

        library = list_materials()
        known = set(FIRST_MATERIALS) | {LIBRARY_PREFIX + name for name in library}
        unknown = sorted({v for v in value.values() if v not in known})
        if unknown:
            raise ValueError(
                f"unknown material(s) {', '.join(unknown)}; choose a built-in "
                f"({', '.join(sorted(FIRST_MATERIALS))}) or a library material "
                f"({', '.join(LIBRARY_PREFIX + name for name in library)})"
            )
        return value


class TargetConfig(_Strict):
    """Exactly one of ``procedural`` or ``mesh``, and the keypoints to label."""

    procedural: ProceduralTargetConfig | None = None
    mesh: MeshTargetConfig | None = None
    keypoints: KeypointsConfig = Field(default_factory=KeypointsConfig)

    @model_validator(mode="after")
    def _exactly_one(self) -> TargetConfig:
        if (self.procedural is None) == (self.mesh is None):
            raise ValueError("give exactly one of 'procedural' or 'mesh'")
        return self

    def build(self, band_nm: tuple[float, float] | None = None) -> TargetMesh:
        """The target mesh this section asks for (procedural or loaded from a file).
        Library materials (a mesh part's ``library:NAME``, or a procedural satellite's
        ``materials: library``) take their colour from the band ``band_nm`` (the scenario's
        ``sun.band_nm``; default 450-900 nm)."""
        band_nm = band_nm or DEFAULT_BAND_NM
        p, m = self.procedural, self.mesh
        if p is not None:
            library = p.materials == "library"
            return satellite(
                p.satellite_class, p.seed, p.smooth_normals, p.textures,
                band_nm if library else None,
            )  # fmt: skip
        requested = [v for v in m.materials.values() if v.startswith(LIBRARY_PREFIX)]
        pool = {**FIRST_MATERIALS}
        if requested:
            pool.update(library_materials(requested, band_nm))
        from satsight.scene.loading import load_mesh  # (the mesh tools: 0.6 s to import)

        return load_mesh(
            m.path,
            scale_m=m.scale_m,
            materials=pool,
            builtin_materials=m.materials,
            crease_angle_deg=m.crease_angle_deg,
            strict_textures=m.strict_textures,
        )

    def with_paths_from(self, folder: Path) -> TargetConfig:
        """This section with a relative mesh or keypoints path taken from ``folder`` (the
        scenario file's); itself when there is none."""
        update = {}
        if self.mesh is not None and not self.mesh.path.is_absolute():
            update["mesh"] = self.mesh.model_copy(
                update={"path": (folder / self.mesh.path).resolve()}
            )
        path = self.keypoints.path
        if path is not None and not path.is_absolute():
            update["keypoints"] = self.keypoints.model_copy(
                update={"path": (folder / path).resolve()}
            )
        return self.model_copy(update=update) if update else self
