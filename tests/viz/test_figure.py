"""Tests for camvlp.viz.figure: figures that leave the process's matplotlib state alone."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "camvlp"


def test_a_figure_is_saved_without_touching_the_backend_or_pyplot(tmp_path):
    png = tmp_path / "f.png"
    code = (
        "import sys, matplotlib\n"
        "matplotlib.use('svg')\n"
        "from camvlp.viz.figure import new_figure\n"
        "fig = new_figure(2, 1.5, dpi=50)\n"
        "fig.add_subplot().plot([0, 1], [1, 0])\n"
        f"fig.savefig({str(png)!r})\n"
        "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend()\n"
        "assert 'matplotlib.pyplot' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_no_module_sets_the_backend_or_uses_pyplot():
    offenders = [
        p.relative_to(SRC).as_posix()
        for p in SRC.rglob("*.py")
        if any(
            s in p.read_text()
            for s in (
                "matplotlib.use(",
                "import matplotlib.pyplot",
                "from matplotlib import pyplot",
            )
        )
    ]
    assert offenders == []
