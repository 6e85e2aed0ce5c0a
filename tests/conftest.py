"""Shared test fixtures: paths to the example files and to the shared data directory."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def examples_dir() -> Path:
    """The repository's ``examples/`` directory."""
    return REPO / "examples"


@pytest.fixture(scope="session")
def thesis_camera_path(examples_dir: Path) -> Path:
    """``examples/thesis_camera.yaml``: the thesis' phone camera."""
    return examples_dir / "thesis_camera.yaml"


@pytest.fixture(scope="session")
def thesis_room_path(examples_dir: Path) -> Path:
    """``examples/thesis_room.yaml``: the thesis' four-fixture room."""
    return examples_dir / "thesis_room.yaml"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The shared data directory next to the repository (real photographs, thesis text)."""
    return REPO.parent / "shared"
