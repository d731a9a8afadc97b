"""Draw the material library's spectra (docs/images/material_spectra.png) and print the
in-band table for the default 450-900 nm band as JSON.

Run: .venv/bin/python benchmarks/material_spectra_figure.py [output.png]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from satsight.scene.material_plot import materials_report, plot_library_spectra

DEFAULT_OUTPUT = Path(__file__).resolve().parents[1] / "docs" / "images" / "material_spectra.png"


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_OUTPUT
    plot_library_spectra(out)
    print(
        json.dumps(
            {"figure": str(out), "band_nm": [450, 900], "rows": materials_report()}, indent=1
        )
    )


if __name__ == "__main__":
    main()
