"""The thesis' camera and room, loaded once for the study tests (``from study_helpers import
cam, room``)."""

from __future__ import annotations

import pytest

from camvlp.io import load_camera, load_map


@pytest.fixture(scope="session")
def cam(thesis_camera_path):
    """The thesis' camera (``examples/thesis_camera.yaml``)."""
    return load_camera(thesis_camera_path)


@pytest.fixture(scope="session")
def room(thesis_room_path):
    """The thesis' room (``examples/thesis_room.yaml``)."""
    return load_map(thesis_room_path)
