"""Tests for camvlp.sim.grid: camera centres over the floor for studies and surveys."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.io import load_map
from camvlp.sim.grid import axis_values, floor_grid, grid_points, set_height


@pytest.fixture(scope="module")
def room(thesis_room_path):
    return load_map(thesis_room_path)


# ----------------------------------------------------------------------------- helpers


def test_grid_helpers(room):
    np.testing.assert_allclose(axis_values((-1, 1), 0.1, "x"), np.linspace(-1, 1, 21))
    assert axis_values((0, 1), 0.3).tolist() == [0.0, 0.3, 0.6, 0.9]
    with pytest.raises(ValueError, match="x range"):
        floor_grid(room.positions, u_range_m=(1, -1))
    with pytest.raises(ValueError, match="plane"):
        floor_grid(room.positions, plane="xx")
    pos = set_height([(0.5, 0, 0)], room.positions, height_m=1.0)
    np.testing.assert_allclose(pos, [[0.5, -1.0, 0.0]])


def test_grid_points_include_stop_and_level():
    grid = grid_points((-0.4, 0.4, 0.1), (-0.4, 0.4, 0.1), -1.0)
    assert grid.shape == (81, 3)
    assert np.allclose(np.unique(grid[:, 0].round(9)), np.linspace(-0.4, 0.4, 9))
    assert np.all(grid[:, 1] == -1.0)
    assert not np.any(np.signbit(grid_points((0, 0, 1), (0, 0, 1), -0.0)))
    with pytest.raises(ValueError, match="step"):
        grid_points((0, 1, 0), (0, 1, 0.5), 0.0)


def test_the_study_and_the_survey_grids_are_the_same_points(room):
    # the study's grid at 1 m (y down in the thesis' room) against the survey's list
    _, _, pos = floor_grid(
        room.positions, u_range_m=(-0.5, 0.5), v_range_m=(0, 1), step_m=0.25, height_m=1.0
    )
    listed = grid_points((-0.5, 0.5, 0.25), (0, 1, 0.25), -1.0)
    assert pos.shape == (5, 5, 3)
    np.testing.assert_allclose(np.sort(pos.reshape(-1, 3), axis=0), np.sort(listed, axis=0))
