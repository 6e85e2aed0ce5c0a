"""Write the supermarket site (``examples/supermarket_layout.yaml``, then its IDs with
``camvlp assign-ids``: ``examples/supermarket.yaml`` and ``docs/sites/assign_ids.png``).

A shop floor of 60 m x 40 m under a 3.5 m ceiling: 600 downlights of 20 cm in 15 rows
across the aisles (2.67 m apart), 40 a row (1.5 m apart), sending the thesis' 4-bit frame
(16 IDs, each reused on some 37 fixtures). The IDs are assigned for the thesis' phone
camera (``examples/thesis_camera.yaml``) held 1.0 to 1.6 m above the floor, tilted up to
20 degrees, any heading.

    python examples/make_supermarket.py
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def main() -> None:
    x = 0.75 + 1.5 * np.arange(40)
    y = 40.0 / 15 * (0.5 + np.arange(15))
    xx, yy = np.meshgrid(x, y)
    fixtures = [
        {"position": [round(float(a), 3), round(float(b), 3), 3.5], "diameter": 0.2}
        for a, b in zip(xx.ravel(), yy.ravel(), strict=True)
    ]
    layout = {
        "units": "m",
        "frame": {"preamble": "111", "id_bits": 4, "postamble": "00", "chip_rate_hz": 10000.0},
        "up": [0, 0, 1],
        "fixtures": [{**f, "normal": [0, 0, -1]} for f in fixtures],
    }
    path = HERE / "supermarket_layout.yaml"
    head = "# A supermarket's ceiling, 60 m x 40 m, 3.5 m up: 600 downlights without IDs\n"
    path.write_text(head + yaml.safe_dump(layout, sort_keys=False, default_flow_style=None))
    print(f"{path}: {len(fixtures)} fixtures")
    plot = ROOT / "docs" / "sites" / "assign_ids.png"
    plot.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "camvlp", "assign-ids", str(path), "--camera",
           str(HERE / "thesis_camera.yaml"), "--out", str(HERE / "supermarket.yaml"),
           "--plot", str(plot)]  # fmt: skip
    subprocess.run(cmd, check=True)


if __name__ == "__main__":
    main()
