"""Command-line interface: a thin layer that parses arguments and calls the library."""

from __future__ import annotations

from . import encode  # noqa: F401  (registers commands)
from . import render as _render  # noqa: F401  (registers commands)
from ._app import app

__all__ = ["app", "main"]


def main() -> None:
    """Entry point of the ``camvlp`` console script."""
    app()
