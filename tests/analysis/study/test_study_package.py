"""Tests for the study package's public names, and the names that moved out of it."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import camvlp.analysis.study as study

MOVED = [
    ("camvlp.analysis.study", "plot_rounding", "camvlp.viz.study_plots"),
    ("camvlp.analysis.study", "write_outputs", "camvlp.io.writers"),
    ("camvlp.analysis.evaluate", "plot_positions", "camvlp.viz.evaluate_plots"),
    ("camvlp.analysis.evaluate", "RESULT_COLUMNS", "camvlp.io.writers"),
    ("camvlp.sim.survey", "floor_grid", "camvlp.sim.grid"),
]


def test_every_public_name_resolves():
    for name in study.__all__:
        assert getattr(study, name) is not None


@pytest.mark.parametrize(("old", "name", "home"), MOVED)
def test_moved_names_still_import_with_a_warning_naming_their_home(old, name, home):
    with pytest.warns(DeprecationWarning, match=home):
        obj = getattr(importlib.import_module(old), name)
    new_name = "grid_points" if name == "floor_grid" else name
    assert obj is getattr(importlib.import_module(home), new_name)
    with pytest.raises(AttributeError):
        _ = importlib.import_module(old).no_such_name


def test_the_study_does_not_import_matplotlib_until_a_plot_is_made():
    code = (
        "import sys, camvlp.analysis.study, camvlp.analysis.evaluate, camvlp.viz.study_plots\n"
        "assert 'matplotlib' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
