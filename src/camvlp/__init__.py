"""camvlp: visible light positioning with a rolling-shutter camera.

Find a camera's position from one photograph of coded ceiling lights: detect the fixtures,
decode their IDs, look them up in a map of the room, and solve Perspective-n-Point.
"""

from camvlp import _moved
from camvlp.errors import InputError
from camvlp.io import load_camera, load_image, load_map, save_camera, save_map
from camvlp.model.camera import Camera, Pose, euler_to_matrix, matrix_to_euler, project_points
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.linecode import ChipDecode, FrameFormat, chip_schedule, manchester_encode
from camvlp.pipeline.locate import FixtureResult, LocateResult, LocateSettings, locate
from camvlp.sim.render import (
    FixtureTruth,
    Render,
    RenderSettings,
    all_fully_inside,
    fixture_truths,
    render,
    save_render,
    tilt_limit,
)

_moved.install()

__version__ = "0.1.0"

__all__ = [
    "Camera",
    "ChipDecode",
    "Fixture",
    "FixtureMap",
    "FixtureResult",
    "FixtureTruth",
    "FrameFormat",
    "InputError",
    "LocateResult",
    "LocateSettings",
    "Pose",
    "Render",
    "RenderSettings",
    "all_fully_inside",
    "chip_schedule",
    "euler_to_matrix",
    "fixture_truths",
    "load_camera",
    "load_image",
    "load_map",
    "locate",
    "manchester_encode",
    "matrix_to_euler",
    "project_points",
    "render",
    "save_camera",
    "save_map",
    "save_render",
    "tilt_limit",
]
