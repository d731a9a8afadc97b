"""The exposure rule: how long each frame integrates.

``mode = "auto"`` picks, per frame, the time that puts the ``percentile`` of the target's
focal-plane irradiance at ``fill_fraction`` of full well (a few brighter glints may
saturate), clipped to [``min_time_s``, ``max_time_s``]; frames with no lit target use
``time_s``. ``mode = "fixed"`` uses ``time_s`` for every frame. The sensor chain applies
it (``SensorChain.exposure_time_s``); ``satsight.config.sensor.ExposureConfig`` validates
a scenario's ``camera.exposure`` and builds it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class ExposureRule:
    """One camera's exposure rule (module docstring). Times in seconds; ``fill_fraction``
    of full well in (0, 1]; ``percentile`` in (0, 100]."""

    mode: Literal["auto", "fixed"] = "auto"
    time_s: float = 0.01
    fill_fraction: float = 0.7
    percentile: float = 99.0
    min_time_s: float = 1e-5
    max_time_s: float = 10.0
