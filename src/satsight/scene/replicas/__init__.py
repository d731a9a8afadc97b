"""Replicas of real spacecraft, built from their published dimensions and layouts.

Six classes, selectable like the procedural ones (``target.procedural.satellite_class``,
``satsight satellite CLASS``):

* ``icesat2``: ICESat-2 (NASA), LEOStar-3 bus, ATLAS lidar, one four-panel wing;
* ``oco2``: OCO-2 (NASA/JPL), LEOStar-2 hexagonal bus, two wings;
* ``galaxy19``: Galaxy 19 (Intelsat), SS/L 1300 geostationary bus, two reflectors, wings
  spanning about 27 m;
* ``cloudsat``: CloudSat (NASA/JPL), BCP-2000 bus, the 1.85 m Cloud Profiling Radar dish;
* ``jason2``: Jason-2/OSTM (CNES/NASA), Proteus bus, Poseidon-3 altimeter dish;
* ``tango``: Tango of the PRISMA mission (SSC), the SPEED/SPEED+ pose-estimation target,
  a 0.57 x 0.74 x 0.3 m box with a fixed solar panel and three antennas.

Each module cites its sources and says which figures are estimated. Replicas keep their
real size (no rescale into the procedural classes' 2-10 m). Every part is a closed,
outward-facing solid with a unique name and a material of the spectral library
(``library:NAME``), its colour integrated over the scenario's band. The seed turns only
the solar-array drive angle (uniform in [-60, 60] degrees about cells facing +x; Tango's
panel is fixed, so its seed changes nothing). Body frames are given per module; all put
the origin at the bus centre, the main instrument's boresight along +z and the wing
axis along y.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from satsight.scene.materials import Material
from satsight.scene.mesh import TargetMesh, merge_parts
from satsight.scene.normals import DEFAULT_CREASE_ANGLE_DEG
from satsight.scene.primitives import Parts
from satsight.scene.replicas import cloudsat, galaxy19, icesat2, jason2, oco2, tango
from satsight.scene.satellite_classes import REPLICA_CLASSES as REPLICA_CLASSES

_BUILDERS: dict[str, Callable[[Parts, np.random.Generator], None]] = {
    "icesat2": icesat2.build,
    "oco2": oco2.build,
    "galaxy19": galaxy19.build,
    "cloudsat": cloudsat.build,
    "jason2": jason2.build,
    "tango": tango.build,
}

# REPLICA_CLASSES (satellite_classes.py) names these builders, in this order (tested).


def build_replica(
    replica_class: str,
    seed: int,
    materials: Mapping[str, Material],
    smooth_normals: bool = False,
    textures: bool = False,
) -> TargetMesh:
    """The replica ``replica_class`` (one of ``REPLICA_CLASSES``) in its body frame.

    materials: a mapping that holds the library materials as ``library:NAME`` and the
    built-in names the textures take their colours from (``solar_cell``,
    ``panel_substrate``, ``white_paint``): ``band_reflectance.BandMaterials``. Only the
    materials the parts use are kept in the mesh. seed: turns the solar-array drive
    (``np.random.default_rng(seed)``); textures draw from ``default_rng([seed, 1])``.
    """
    rng = np.random.default_rng(int(seed))
    parts = Parts(np.random.default_rng([int(seed), 1]) if textures else None, materials)
    _BUILDERS[replica_class](parts, rng)
    used = {item[1] for item in parts.items}
    return merge_parts(
        parts.items,
        materials={name: materials[name] for name in sorted(used)},
        name=f"{replica_class}-seed{seed}",
        crease_angle_deg=DEFAULT_CREASE_ANGLE_DEG if smooth_normals else None,
    )
