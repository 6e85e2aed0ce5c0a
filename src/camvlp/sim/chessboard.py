"""Synthetic chessboard photographs: the calibration target seen by a known camera.

:func:`board_object_points` gives the board's inner corners in its own frame (OpenCV's
detection order); :func:`render_chessboard` renders the photograph a camera at a pose would
take of it, lens distortion included.  :mod:`camvlp.analysis.calibrate` finds the corners in
real or rendered photos and calibrates from them; tests and benchmarks check it on renders of
a camera they know; :func:`chessboard_views` renders a calibration set (``camvlp
render-chessboard``): random poses that see the whole board, blur and noise.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.model.camera import Camera, Pose, rotation_x, rotation_z

__all__ = [
    "ChessboardView",
    "board_object_points",
    "board_poses",
    "chessboard_views",
    "parse_board",
    "render_chessboard",
]


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


#: The lens model is inverted at every ``_LENS_STRIDE``-th supersampled pixel along each axis
#: and interpolated between (bilinear): a smooth distortion's inverse is then off by under a
#: thousandth of a pixel (k1 = -0.12 at 640 x 480), in a sixteenth of the time.
_LENS_STRIDE = 4


def _ray_directions(camera: Camera, size: tuple[int, int], n: int) -> np.ndarray:
    """``(x/z, y/z)`` of the ray through each pixel of the supersampled picture ``size``
    (``n`` per pixel along each axis), shape (size[0] * size[1], 2), row by row."""
    w, h = size
    gu = np.unique(np.r_[np.arange(0, w, _LENS_STRIDE), w - 1])
    gv = np.unique(np.r_[np.arange(0, h, _LENS_STRIDE), h - 1])
    uu, vv = np.meshgrid((gu - (n - 1) / 2) / n, (gv - (n - 1) / 2) / n)
    coarse = camera.undistort_pixels(np.column_stack([uu.ravel(), vv.ravel()]))
    coarse = coarse.reshape(len(gv), len(gu), 2)
    if len(gu) < 2 or len(gv) < 2:  # a picture a few pixels wide: every ray inverted
        uu, vv = np.meshgrid((np.arange(w) - (n - 1) / 2) / n, (np.arange(h) - (n - 1) / 2) / n)
        return camera.undistort_pixels(np.column_stack([uu.ravel(), vv.ravel()]))
    ax, ay = _linear_weights(w, gu), _linear_weights(h, gv)  # separable bilinear
    x = ay @ coarse[..., 0] @ ax.T
    y = ay @ coarse[..., 1] @ ax.T
    return np.column_stack([x.ravel(), y.ravel()])


def _linear_weights(count: int, grid: np.ndarray) -> np.ndarray:
    """Weights, shape (count, len(grid)), that interpolate linearly between samples at the
    pixels ``grid`` (increasing, from 0 to ``count - 1``) to each of ``count`` pixels."""
    pos = np.arange(count)
    j = np.clip(np.searchsorted(grid, pos, side="right") - 1, 0, len(grid) - 2)
    t = (pos - grid[j]) / (grid[j + 1] - grid[j])
    weights = np.zeros((count, len(grid)))
    weights[pos, j] = 1 - t
    weights[pos, j + 1] = t
    return weights


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
        xy = _ray_directions(camera, size, n)
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


#: Most supersampled pixels :func:`chessboard_views` renders a view with (its own choice of
#: ``supersample``: 3 for a VGA camera, 2 up to 1 megapixel, 1 above).
MAX_SUPERSAMPLED_PX = 4_000_000
#: Least distance (pixels) between the board's margin and the picture's edge in a view.
EDGE_PX = 5.0


def board_outline(board: tuple[int, int], square_m: float) -> np.ndarray:
    """The outer corners of the board's white margin, shape (4, 3), metres (board frame)."""
    cols, rows = parse_board(board)
    corners = np.array([[-2, -2], [cols + 1, -2], [-2, rows + 1], [cols + 1, rows + 1]])
    return np.column_stack([corners * float(square_m), np.zeros(4)])


def board_poses(
    camera: Camera,
    board: tuple[int, int],
    square_m: float,
    n: int,
    rng: np.random.Generator,
    *,
    tilt_deg: tuple[float, float] = (20.0, 40.0),
    fill: tuple[float, float] = (0.55, 0.8),
) -> list[Pose]:
    """``n`` random poses from which ``camera`` sees the whole board, margin included.

    Each looks at the board tilted by ``tilt_deg`` (degrees, uniform) about a random axis in
    the board's plane, rolled by up to 30 degrees, from the distance at which the board fills
    a fraction ``fill`` (uniform) of the picture's width or height (whichever it fills
    first), shifted at random within the rest; poses that put the margin within
    ``EDGE_PX`` of the picture's edge (lens distortion included) are drawn again.

    Returns
    -------
    list of Pose
        Camera poses in the board's frame (metres), see :func:`render_chessboard`.

    Raises
    ------
    ValueError
        ``n`` below 1, or the board fits the picture too rarely (50 draws per pose).
    """
    cols, rows = parse_board(board)
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    s = float(square_m)
    centre = np.array([(cols - 1) / 2, (rows - 1) / 2, 0.0]) * s
    outline = board_outline(board, s)
    k = camera.matrix
    half_field = np.array([camera.width / k[0, 0], camera.height / k[1, 1]]) / 2
    size = max((cols + 3) * s / (2 * half_field[0]), (rows + 3) * s / (2 * half_field[1]))
    poses: list[Pose] = []
    for _ in range(50 * n):
        az, tilt, roll = rng.uniform(0, 360), rng.uniform(*tilt_deg), rng.uniform(-30, 30)
        r = rotation_z(az) @ rotation_x(tilt) @ rotation_z(-az) @ rotation_z(roll)
        share = rng.uniform(*fill)
        distance = size / share
        shift = rng.uniform(-1, 1, 2) * (1 - share) * distance * half_field
        pose = Pose(r, centre - distance * r[:, 2] + r[:, :2] @ shift)
        uv = camera.project(pose, outline)
        inside = np.all(uv > EDGE_PX) and np.all(uv < np.array(camera.size) - EDGE_PX)
        if np.all(np.isfinite(uv)) and inside:
            poses.append(pose)
            if len(poses) == n:
                return poses
    raise ValueError(
        f"the {cols}x{rows} board, its margin included, fits within the picture too rarely "
        f"(fewer than {n} of {50 * n} poses drawn)"
    )


@dataclass(frozen=True)
class ChessboardView:
    """One rendered view of the board.

    Attributes
    ----------
    image : ndarray, shape (height, width), uint8
        The photograph (blurred, with noise).
    pose : Pose
        The camera's pose in the board's frame (metres).
    corners_px : ndarray, shape (cols * rows, 2)
        The inner corners' true pixels, in :func:`board_object_points`' order.
    """

    image: np.ndarray
    pose: Pose
    corners_px: np.ndarray


def chessboard_views(
    camera: Camera,
    board: tuple[int, int],
    square_m: float,
    n: int,
    *,
    seed: int = 0,
    blur_px: float = 0.7,
    noise: float = 2.0,
    supersample: int | None = None,
) -> Iterator[ChessboardView]:
    """Render ``n`` photographs of a chessboard at random poses (:func:`board_poses`), as
    ``camera`` (its intrinsics and lens distortion) would take them.

    Parameters
    ----------
    camera : Camera
    board : (int, int)
        Inner corners ``(cols, rows)``.
    square_m : float
        Side of one square, metres.
    n : int
        Views.
    seed : int
        Seed of the poses and the noise.
    blur_px : float
        Optical blur, Gaussian sigma in pixels (0: none).
    noise : float
        Sensor noise, Gaussian sigma in grey levels (0 to 255 scale; 0: none).
    supersample : int, optional
        Rays per pixel along each axis; default the most, up to 3, that keeps a view within
        ``MAX_SUPERSAMPLED_PX``.

    Yields
    ------
    ChessboardView
        One view at a time (the poses are drawn first, so ``n`` views or none).
    """
    if not (np.isfinite(blur_px) and 0 <= blur_px <= 100):
        raise ValueError(f"blur_px must be from 0 to 100 pixels, got {blur_px!r}")
    if not (np.isfinite(noise) and 0 <= noise <= 255):
        raise ValueError(f"noise must be from 0 to 255 grey levels, got {noise!r}")
    if supersample is None:
        area = camera.width * camera.height
        supersample = next((k for k in (3, 2) if area * k * k <= MAX_SUPERSAMPLED_PX), 1)
    rng = np.random.default_rng(seed)
    poses = board_poses(camera, board, square_m, n, rng)
    points = board_object_points(board, square_m)
    for pose in poses:
        img = render_chessboard(camera, pose, board, square_m, supersample=supersample)
        img = img.astype(np.float32)
        if blur_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur_px)
        if noise > 0:
            img += rng.normal(0.0, noise, img.shape).astype(np.float32)
        image = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        yield ChessboardView(image, pose, camera.project(pose, points))
