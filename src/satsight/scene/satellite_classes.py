"""The names of the procedural satellite classes and of the replicas of real spacecraft,
apart from their builders (``satsight.scene.procedural``, ``satsight.scene.replicas``), so
that a scenario can be checked without loading the mesh tools those import."""

from __future__ import annotations

SATELLITE_CLASSES: tuple[str, ...] = (
    "body_mounted",
    "one_wing",
    "two_wings",
    "four_panels",
    "two_wings_dish",
)
REPLICA_CLASSES: tuple[str, ...] = ("icesat2", "oco2", "galaxy19", "cloudsat", "jason2", "tango")
