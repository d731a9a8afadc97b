"""Render the six replicas at 1 km, sunlit, and tile their radiance (in colour, scaled
per tile) into docs/images/replicas.png (run: .venv/bin/python docs/make_replicas_figure.py)."""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from satsight.config.scenario import parse_scenario
from satsight.dataset.image_files import read_exr
from satsight.run.generation import generate_dataset
from satsight.scene.procedural import generate_satellite
from satsight.scene.replicas import REPLICA_CLASSES

TITLES = {
    "icesat2": "ICESat-2",
    "oco2": "OCO-2",
    "galaxy19": "Galaxy 19",
    "cloudsat": "CloudSat",
    "jason2": "Jason-2",
    "tango": "Tango (PRISMA)",
}
TILE_PX = 320
# metres per pixel at 1 km: high_resolution 15 um / 3 m, wide_field 15 um / 0.7 m
PRESETS = {"high_resolution": 15e-6 / 3.0 * 1e3, "wide_field": 15e-6 / 0.7 * 1e3}


def render(name: str, folder: Path) -> np.ndarray:
    size_m = float(generate_satellite(name, 0).extent_m.max())
    preset = "high_resolution" if size_m / PRESETS["high_resolution"] < 3000 else "wide_field"
    side = int(min(4096, max(160, 1.7 * size_m / PRESETS[preset]))) // 2 * 2
    scenario = {
        "name": f"replica-{name}",
        "seed": 1,
        "camera": {"preset": preset, "width_px": side, "height_px": side},
        "target": {"procedural": {"satellite_class": name, "seed": 0}},
        "frames": [{"distance_km": 1.0, "azimuth_deg": 40, "elevation_deg": 25, "roll_deg": 0}],
    }
    out = folder / name
    generate_dataset(parse_scenario(scenario), out)
    frame = json.loads((out / "labels.json").read_text(encoding="utf-8"))["frames"][0]
    return _display(read_exr(out / frame["files"]["radiance_exr"])["RGB"])


def _display(radiance_rgb: np.ndarray) -> np.ndarray:
    """8-bit sRGB-like colour of a radiance image: scaled so that the 99.5th percentile of
    the lit pixels is white, then a 1/2.2 gamma (a picture, not a measurement)."""
    lit = radiance_rgb.max(axis=2)
    white = float(np.percentile(lit[lit > 0], 99.5)) if np.any(lit > 0) else 1.0
    shown = np.clip(radiance_rgb / white, 0.0, 1.0) ** (1 / 2.2)
    return np.round(255 * shown).astype(np.uint8)


def main(path: Path) -> None:
    tiles = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in REPLICA_CLASSES:
            image = Image.fromarray(render(name, Path(tmp))).convert("RGB")
            image = image.resize((TILE_PX, TILE_PX), Image.Resampling.LANCZOS)
            ImageDraw.Draw(image).text((8, 8), TITLES[name], fill=(255, 255, 255))
            tiles.append(image)
    grid = Image.new("RGB", (3 * TILE_PX, 2 * TILE_PX))
    for k, tile in enumerate(tiles):
        grid.paste(tile, ((k % 3) * TILE_PX, (k // 3) * TILE_PX))
    path.parent.mkdir(parents=True, exist_ok=True)
    grid.save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "images/replicas.png")
