"""Changing a validated scenario by dotted keys, validated again as a whole.

An override names one value of the scenario document by its path, the section keys (and
list positions) joined by dots, as the validation messages name it::

    {"camera.width_px": 256, "sampler.frame_count": 20, "frames.0.distance_km": 2.5}

A value that is a mapping replaces the whole section. A section that is absent (``None``,
e.g. ``outputs.crop``) is created, so ``{"outputs.crop.size_px": 64}`` adds a crop. The
changed document goes through the same validation as a scenario file, so a misspelt key
or a bad value is reported with its dotted path.
"""

from __future__ import annotations

from collections.abc import Mapping

from satsight.config.scenario import Scenario, parse_scenario
from satsight.errors import SatsightError


def _set_dotted(document: dict, key: str, value: object) -> None:
    """Set ``document[a][b]...[z] = value`` for ``key = "a.b...z"``, in place; integer
    parts index lists, absent (None) sections are created as mappings."""
    parts = key.split(".")
    if not key or any(part == "" for part in parts):
        raise SatsightError(
            f"override {key!r}: expected section keys joined by dots, e.g. 'camera.width_px'"
        )
    container: object = document
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[: depth + 1])
        if isinstance(container, dict):
            if last:
                container[part] = value
            elif container.get(part) is None:
                container[part] = {}
            container = container[part]
        elif isinstance(container, list):
            if not (part.isdigit() and int(part) < len(container)):
                raise SatsightError(
                    f"override {key!r}: {'.'.join(parts[:depth])} is a list of "
                    f"{len(container)} item(s); {where} names no item of it (use 0 to "
                    f"{len(container) - 1}, or replace the whole list)"
                )
            if last:
                container[int(part)] = value
            container = container[int(part)]
        else:
            parent = ".".join(parts[:depth])
            raise SatsightError(
                f"override {key!r}: {parent} is a value ({container!r}), not a section with "
                f"keys; override {parent} itself"
            )


def override_scenario(scenario: Scenario, overrides: Mapping[str, object]) -> Scenario:
    """``scenario`` with the values of ``overrides`` (dotted key -> new value) replaced,
    validated again as a whole; SatsightError naming the key when one is unknown or its
    value is not valid. The scenario itself is not changed (scenarios are frozen)."""
    if not isinstance(overrides, Mapping):
        raise SatsightError(
            f"overrides must be a mapping of dotted keys to values, e.g. "
            f"{{'camera.width_px': 256}}; got {type(overrides).__name__}"
        )
    document = scenario.model_dump(mode="json")
    for key, value in overrides.items():
        if not isinstance(key, str):
            raise SatsightError(f"override key {key!r} is not a string of dotted keys")
        _set_dotted(document, key, value)
    keys = ", ".join(overrides)
    return parse_scenario(document, f"scenario '{scenario.name}' with overrides of {keys}")
