"""camvlp: visible light positioning with a rolling-shutter camera.

Find a camera's position from one photograph of coded ceiling lights: detect the fixtures,
decode their IDs, look them up in a map of the room, and solve Perspective-n-Point.

The names below are loaded on first use (a module ``__getattr__``): ``import camvlp`` alone
loads neither the locator, the simulator, OpenCV nor matplotlib.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: Each public name and the module it lives in.
_HOMES = {
    "InputError": "camvlp.errors",
    "load_camera": "camvlp.io",
    "load_image": "camvlp.io",
    "load_map": "camvlp.io",
    "save_camera": "camvlp.io",
    "save_map": "camvlp.io",
    "Camera": "camvlp.model.camera",
    "Pose": "camvlp.model.camera",
    "euler_to_matrix": "camvlp.model.camera",
    "matrix_to_euler": "camvlp.model.camera",
    "project_points": "camvlp.model.camera",
    "Fixture": "camvlp.model.fixtures",
    "FixtureMap": "camvlp.model.fixtures",
    "ChipDecode": "camvlp.model.linecode",
    "FrameFormat": "camvlp.model.linecode",
    "chip_schedule": "camvlp.model.linecode",
    "manchester_encode": "camvlp.model.linecode",
    "FixtureResult": "camvlp.pipeline.locate",
    "LocateResult": "camvlp.pipeline.locate",
    "LocateSettings": "camvlp.pipeline.locate",
    "locate": "camvlp.pipeline.locate",
    "FixtureTruth": "camvlp.sim.render",
    "Render": "camvlp.sim.render",
    "RenderSettings": "camvlp.sim.render",
    "all_fully_inside": "camvlp.sim.render",
    "fixture_truths": "camvlp.sim.render",
    "render": "camvlp.sim.render",
    "save_render": "camvlp.io.writers",
    "tilt_limit": "camvlp.sim.render",
}

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


def __getattr__(name: str):
    """The public name ``name``, imported from its module on first use."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'camvlp' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    """The module's names, the public ones not yet loaded included."""
    return sorted({*globals(), *_HOMES})


if TYPE_CHECKING:  # what static tools (type checkers, editors, mkdocstrings) see
    from camvlp.errors import InputError
    from camvlp.io import load_camera, load_image, load_map, save_camera, save_map
    from camvlp.io.writers import save_render
    from camvlp.model.camera import (
        Camera,
        Pose,
        euler_to_matrix,
        matrix_to_euler,
        project_points,
    )
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
        tilt_limit,
    )
