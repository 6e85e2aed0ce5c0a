"""Synthetic chessboard photographs: the calibration target seen by a known camera.

:func:`board_object_points` gives the board's inner corners in its own frame (OpenCV's
detection order); :func:`render_chessboard` renders the photograph a camera at a pose would
take of it, lens distortion included.  :mod:`camvlp.analysis.calibrate` finds the corners in
real or rendered photos and calibrates from them; tests and benchmarks check it on renders of
a camera they know.
"""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.model.camera import Camera, Pose

__all__ = ["board_object_points", "parse_board", "render_chessboard"]


#: Fewest inner corners along each side of a board: OpenCV's board detectors
#: (``findChessboardCorners`` and ``findChessboardCornersSB``) refuse 2.
MIN_BOARD_SIDE = 3


def parse_board(board) -> tuple[int, int]:
    """``(cols, rows)`` inner corners as two ints >= ``MIN_BOARD_SIDE``, else ValueError."""
    try:
        cols, rows = (int(v) for v in board)
    except (TypeError, ValueError):
        raise ValueError(f"board must be (cols, rows) inner corners, got {board!r}") from None
    if cols < MIN_BOARD_SIDE or rows < MIN_BOARD_SIDE:
        raise ValueError(
            f"board must have at least {MIN_BOARD_SIDE} x {MIN_BOARD_SIDE} inner corners, "
            f"got {cols} x {rows}"
        )
    return cols, rows


def board_object_points(board: tuple[int, int], square_m: float) -> np.ndarray:
    """The board's inner corners in its own frame, in OpenCV's detection order.

    Parameters
    ----------
    board : (int, int)
        Inner corners ``(cols, rows)``.
    square_m : float
        Side of one square, metres.

    Returns
    -------
    ndarray, shape (cols * rows, 3), float32
        Corner ``(i, j)`` (column ``i``, row ``j``) at ``(i * square_m, j * square_m, 0)``,
        row by row.
    """
    cols, rows = parse_board(board)
    if not (np.isfinite(square_m) and square_m > 0):
        raise ValueError(f"square_m must be a positive number of metres, got {square_m!r}")
    i, j = np.meshgrid(np.arange(cols), np.arange(rows))
    pts = np.stack([i.ravel(), j.ravel(), np.zeros(i.size)], axis=1) * float(square_m)
    return pts.astype(np.float32)


#: Texels per square of the board's texture.
_TEXELS = 32


def _board_texture(
    cols: int, rows: int, square_m: float, black: float, white: float
) -> tuple[np.ndarray, np.ndarray]:
    """The board with its margin as an image, and the homography from board metres to it.

    The texture has :data:`_TEXELS` texels per square and starts at board coordinate
    ``(-2 s, -2 s)``, the margin's outer corner.
    """
    t = _TEXELS
    gx, gy = np.meshgrid(np.arange(cols + 3) - 2, np.arange(rows + 3) - 2)
    squares = np.where((gx + gy) % 2 == 0, black, white)
    squares[(gx < -1) | (gx > cols - 1) | (gy < -1) | (gy > rows - 1)] = white
    texture = np.kron(squares, np.ones((t, t))).astype(np.float32)
    s = square_m
    tex_from_board = np.array([[t / s, 0, 2 * t - 0.5], [0, t / s, 2 * t - 0.5], [0, 0, 1.0]])
    return texture, tex_from_board


def render_chessboard(
    camera: Camera,
    pose: Pose,
    board: tuple[int, int],
    square_m: float,
    *,
    supersample: int = 3,
    black: float = 25.0,
    white: float = 230.0,
    background: float = 110.0,
) -> np.ndarray:
    """Render a photograph of a chessboard seen by a camera (with its lens distortion).

    The board lies in the plane ``z = 0`` of the world frame with its first inner corner at
    the origin, columns along +x and rows along +y (:func:`board_object_points`); its
    ``cols + 1`` by ``rows + 1`` squares are framed by a one-square white margin on a
    uniform background.  Each pixel averages ``supersample ** 2`` rays.

    Parameters
    ----------
    camera : Camera
        Intrinsics, distortion and image size.
    pose : Pose
        The camera's pose in the board's frame (metres).
    board : (int, int)
        Inner corners ``(cols, rows)``.
    square_m : float
        Side of one square, metres.
    supersample : int
        Rays per pixel along each axis (anti-aliasing).
    black, white, background : float
        Gray levels (0-255) of the dark squares, the light squares and margin, and the
        scene around the board.

    Returns
    -------
    ndarray, shape (camera.height, camera.width), uint8
    """
    cols, rows = parse_board(board)
    s = float(square_m)
    if not (np.isfinite(s) and s > 0):
        raise ValueError(f"square_m must be a positive number of metres, got {square_m!r}")
    n = int(supersample)
    if n < 1:
        raise ValueError(f"supersample must be at least 1, got {supersample!r}")
    texture, tex_from_board = _board_texture(cols, rows, s, black, white)
    # Supersampled pixel U = n u + (n - 1) / 2 for pixel u.
    ss_from_pix = np.array([[n, 0, (n - 1) / 2], [0, n, (n - 1) / 2], [0, 0, 1.0]])
    r_cw = pose.camera_from_world
    t_cw = -r_cw @ pose.position
    norm_from_board = np.column_stack([r_cw[:, 0], r_cw[:, 1], t_cw])
    size = (camera.width * n, camera.height * n)
    corners = np.array([[-2, -2], [cols + 1, -2], [-2, rows + 1], [cols + 1, rows + 1]]) * s
    in_front = bool(np.all(pose.to_camera(np.column_stack([corners, np.zeros(4)]))[:, 2] > 0))
    if camera.dist_or_none is None and in_front:
        ss_from_tex = ss_from_pix @ camera.matrix @ norm_from_board @ np.linalg.inv(tex_from_board)
        big = cv2.warpPerspective(
            texture,
            ss_from_tex,
            size,
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=float(background),
        )
    else:  # trace each supersampled ray through the lens model
        uu, vv = np.meshgrid(
            (np.arange(size[0]) - (n - 1) / 2) / n, (np.arange(size[1]) - (n - 1) / 2) / n
        )
        xy = camera.undistort_pixels(np.column_stack([uu.ravel(), vv.ravel()]))
        ray = np.column_stack([xy, np.ones(len(xy))])
        # tex[:, 2] is 1 / depth of the ray's hit on the board plane: > 0 in front.
        tex = ray @ (tex_from_board @ np.linalg.inv(norm_from_board)).T
        front = tex[:, 2] > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            mx = np.where(front, tex[:, 0] / tex[:, 2], -10.0)
            my = np.where(front, tex[:, 1] / tex[:, 2], -10.0)
        big = cv2.remap(
            texture,
            mx.reshape(size[::-1]).astype(np.float32),
            my.reshape(size[::-1]).astype(np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=float(background),
        )
    img = cv2.resize(big, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
