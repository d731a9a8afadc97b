"""satsight: physically based optical images of space objects with exact labels.

The pipeline runs one way, and so do the imports (the layer table in ``docs/design.md``,
held by ``tests/test_import_layers.py``)::

    scenario -> ephemeris -> poses -> scene -> lighting -> render -> sensor -> dataset

All quantities are SI inside; non-SI units appear only at the edges and then in names
(``distance_km``, ``pixel_pitch_um``).

The Python interface (``satsight.api``: ``load_scenario``, ``render_frames``,
``Simulator``, ``generate``, ``open_dataset``, ``export_dataset``) is importable from here.
"""

from satsight.version import __version__

# The Python interface (satsight.api), imported on first use so that ``import satsight``
# loads neither pydantic nor the renderer.
_API_NAMES = (
    "Dataset",
    "DatasetFrame",
    "Frame",
    "Scenario",
    "Simulator",
    "export_dataset",
    "generate",
    "load_scenario",
    "open_dataset",
    "override",
    "render_frames",
)
__all__ = ["SatsightError", "__version__", *_API_NAMES]


def __getattr__(name: str):
    if name in _API_NAMES:
        from satsight import api

        value = getattr(api, name)
        globals()[name] = value  # looked up once
        return value
    if name == "SatsightError":
        from satsight.errors import SatsightError

        return SatsightError
    raise AttributeError(f"module 'satsight' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
