"""Families of the spectral library's materials: those a randomised scene may swap for one
another (a part's material replaced by another of its family keeps what the part is: a
metal stays a metal, an MLI film a film, a cell a cell).

The library's own categories (``material_library.CATEGORIES``) group materials by how
their spectra are made, not by what they are used for (gold and OSR radiators share
``metals_and_osr``), so the families are listed here.
"""

from __future__ import annotations

from satsight.scene.band_reflectance import BUILTIN_LIBRARY_MATCH
from satsight.scene.material_library import LIBRARY_PREFIX

#: Family -> the library materials in it (names without the ``library:`` prefix).
LIBRARY_FAMILIES: dict[str, tuple[str, ...]] = {
    "metal": ("aluminium", "anodised_aluminium", "gold", "silver", "titanium"),
    "film": (
        "mli_aluminised_kapton",
        "aluminium_teflon",
        "silver_teflon",
        "beta_cloth",
        "black_kapton",
        "ge_black_kapton",
    ),
    "paint": ("white_paint_az93", "black_paint_z306"),
    "cell": ("gaas_solar_cell", "si_solar_cell"),
    "radiator": ("osr_fused_silica", "radiator_osr_ceria_glass"),
    "composite": ("cfrp",),
}
_FAMILY_OF = {name: family for family, names in LIBRARY_FAMILIES.items() for name in names}


def library_name(material_name: str) -> str | None:
    """The library material a mesh's material name stands for: ``library:NAME`` is NAME,
    a built-in name its ``BUILTIN_LIBRARY_MATCH``; None for the others."""
    if material_name.startswith(LIBRARY_PREFIX):
        return material_name.removeprefix(LIBRARY_PREFIX)
    return BUILTIN_LIBRARY_MATCH.get(material_name)


def swap_candidates(material_name: str) -> tuple[str, ...]:
    """The library materials (without prefix) that may replace ``material_name``: the
    others of its family, in the table's order (empty when it has no family or is alone)."""
    name = library_name(material_name)
    family = _FAMILY_OF.get(name) if name is not None else None
    if family is None:
        return ()
    return tuple(n for n in LIBRARY_FAMILIES[family] if n != name)
