"""Tests for camvlp.sim.chessboard: the board's geometry and its rendered photograph."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.model.camera import Camera, Pose, rotation_x
from camvlp.sim.chessboard import board_object_points, parse_board, render_chessboard

BOARD = (5, 4)
SQUARE_M = 0.04


def test_board_points_run_row_by_row_in_the_board_plane():
    pts = board_object_points(BOARD, SQUARE_M)
    assert pts.shape == (20, 3) and pts.dtype == np.float32
    np.testing.assert_allclose(
        pts[:6],
        [[0, 0, 0], [0.04, 0, 0], [0.08, 0, 0], [0.12, 0, 0], [0.16, 0, 0], [0, 0.04, 0]],
        atol=1e-7,
    )
    with pytest.raises(ValueError, match="3 x 3"):
        parse_board((1, 4))
    with pytest.raises(ValueError, match="3 x 3"):  # OpenCV's detectors refuse a side of 2
        parse_board((2, 4))
    with pytest.raises(ValueError, match="square_m"):
        board_object_points(BOARD, 0.0)


def test_squares_are_dark_and_light_where_the_camera_model_puts_them():
    # camera 0.5 m in front of the board's centre, looking along +z at it
    cam = Camera.from_focal(320, 240, 300.0)
    centre = np.array([2.0, 1.5, 0.0]) * SQUARE_M
    pose = Pose(rotation_x(0.0), centre - np.array([0.0, 0.0, 0.5]))
    img = render_chessboard(cam, pose, BOARD, SQUARE_M, black=20, white=230, background=110)
    # centres of square (i, j) between inner corners: dark when i + j is even
    squares = [(i + 0.5, j + 0.5) for i in range(4) for j in range(3)]
    pts = np.array([[i * SQUARE_M, j * SQUARE_M, 0.0] for i, j in squares])
    uv = np.rint(cam.project(pose, pts)).astype(int)
    levels = img[uv[:, 1], uv[:, 0]]
    dark = np.array([(int(i) + int(j)) % 2 == 0 for i, j in squares])
    assert np.all(levels[dark] < 40) and np.all(levels[~dark] > 210)
    assert img[2, 2] == 110  # the scene around the board
