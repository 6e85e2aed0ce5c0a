"""Stage 0, prepare: the photo checked against its camera, its levels mapped back to light,
flipped back when mirrored; the gravity direction checked against the map."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.gravity import check_gravity, check_gravity_view, map_up
from camvlp.imaging.tone import linear_light
from camvlp.io.images import as_image
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.settings import MIN_SIDE_PX, LocateSettings

__all__ = ["Prepared", "fitted_camera", "prepare"]


@dataclass(frozen=True)
class Prepared:
    """A photo ready for the stages (:func:`prepare`).

    Attributes
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photo as the sensor saw it: its levels mapped back to light when the camera gives
        its tone curve, flipped back left-right when it was mirrored.
    camera : Camera
        The camera for the photo's size (turned a quarter turn with a photo stored turned).
    mirrored : bool
        The photo as given is mirrored (``image`` is flipped back).
    gravity : tuple of ndarray, shape (3,) each, or None
        The gravity direction in the camera's frame and the map's up, when given.
    outlier_px : float
        Reprojection error beyond which a fixture does not fit the pose, pixels.
    notes : tuple of str
        What the user should know (a camera turned with the photo).
    """

    image: np.ndarray
    camera: Camera
    mirrored: bool
    gravity: tuple[np.ndarray, np.ndarray] | None
    outlier_px: float
    notes: tuple[str, ...] = ()

    def shown(self, pixel: np.ndarray) -> np.ndarray:
        """A pixel ``[u, v]`` of :attr:`image` in the photo as given (mirrored back)."""
        if not self.mirrored:
            return pixel
        return np.array([self.image.shape[1] - 1 - pixel[0], pixel[1]])


def prepare(
    image: np.ndarray,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings,
    gravity=None,
) -> Prepared:
    """Stage 0: the photo checked and made ready for the stages.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photograph, BGR or gray, 8- or 16-bit, of the camera's size (or turned a quarter
        turn, :func:`fitted_camera`).
    camera, fixture_map, settings
        As :func:`~camvlp.pipeline.locate.locate` takes them.
    gravity : array_like, shape (3,), optional
        The gravity direction in the camera's frame.

    Raises
    ------
    InputError
        An image that is not one, of another size; a gravity that is not a direction or
        leaves the map's lights out of view.
    """
    st = settings
    outlier_px = st.outlier_px if st.outlier_px is not None else max(4.0, 0.01 * camera.focal_px)
    img = check_dims(image)
    camera, note = fitted_camera(camera, img.shape[1], img.shape[0])
    img, mirrored = prepared_image(img, camera, st)
    down = None if gravity is None else checked_gravity(gravity, camera, fixture_map)
    return Prepared(img, camera, mirrored, down, outlier_px, (note,) if note else ())


def fitted_camera(camera: Camera, width: int, height: int) -> tuple[Camera, str]:
    """The camera for a photo of ``width`` x ``height`` pixels, and a note ("" or why it was
    turned): the camera itself, or turned a quarter turn (:meth:`Camera.turned`) for a photo
    stored the other way round when the way it was turned does not matter.

    Raises
    ------
    InputError
        The photo is of another size, or turned where the way it was turned would matter.
    """
    if (width, height) == (camera.width, camera.height):
        return camera, ""
    turned = camera.turned() if (height, width) == (camera.width, camera.height) else None
    if turned is not None:
        return turned, (
            f"the photo is {width} x {height}, the camera file's {camera.width} x "
            f"{camera.height} turned a quarter turn: the camera is turned with it"
        )
    hint = (
        " (turned? the camera file describes the other orientation, and its principal point "
        "or distortion depend on which way: write a camera file for this orientation)"
        if (height, width) == (camera.width, camera.height)
        else ""
    )
    raise InputError(
        f"image is {width} x {height} but the camera file says {camera.width} x "
        f"{camera.height}{hint}"
    )


def check_dims(image) -> np.ndarray:
    """The image as an array (:func:`~camvlp.io.images.as_image`) of a photo's dimensions."""
    img = as_image(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise InputError(f"image must be (H, W) gray or (H, W, 3) BGR, got shape {img.shape}")
    return img


def check_image(image: np.ndarray, camera: Camera) -> np.ndarray:
    """The image as an array (:func:`check_dims`), InputError unless of the camera's size and
    large enough to locate."""
    img = check_dims(image)
    h, w = img.shape[:2]
    if (w, h) != (camera.width, camera.height):
        raise InputError(
            f"image is {w} x {h} but the camera file says {camera.width} x {camera.height}"
        )
    if min(h, w) < MIN_SIDE_PX:
        raise InputError(
            f"image is {w} x {h} pixels, too small to locate "
            f"(at least {MIN_SIDE_PX} x {MIN_SIDE_PX})"
        )
    return img


def prepared_image(
    image: np.ndarray, camera: Camera, st: LocateSettings
) -> tuple[np.ndarray, bool]:
    """The checked image, its levels mapped back to light when the camera gives its
    tone curve, flipped left-right when the photo is mirrored."""
    img = check_image(image, camera)
    if camera.tone_gamma is not None:
        img = linear_light(img, camera.tone_gamma)
    mirrored = camera.mirrored if st.mirrored is None else bool(st.mirrored)
    # flipped into a new array: a view of negative stride costs every later OpenCV call a
    # copy (the decimation of a 34 MP photo: 0.7 s against 10 ms)
    return (cv2.flip(img, 1) if mirrored else img), mirrored


def checked_gravity(
    gravity, camera: Camera, fixture_map: FixtureMap
) -> tuple[np.ndarray, np.ndarray]:
    """The checked gravity direction (the camera's own frame: that of the photo unmirrored)
    and the map's up; InputError when the lights are out of the camera's view."""
    g = check_gravity(gravity)
    normals = np.array(
        [f.normal if f.normal is not None else [np.nan] * 3 for f in fixture_map.fixtures]
    )
    up = map_up(fixture_map.positions, up=fixture_map.up, normals=normals)
    check_gravity_view(g, camera, up, normals)
    return g, up
