"""Tests for the study package's public names."""

from __future__ import annotations

import subprocess
import sys

import camvlp.analysis.study as study


def test_every_public_name_resolves():
    for name in study.__all__:
        assert getattr(study, name) is not None


def test_the_study_does_not_import_matplotlib_until_a_plot_is_made():
    code = (
        "import sys, camvlp.analysis.study, camvlp.analysis.evaluate, camvlp.viz.study_plots\n"
        "assert 'matplotlib' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
