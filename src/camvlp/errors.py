"""The package's error for bad input, and its result convention.

Bad input (a missing, unreadable or malformed file or array, an option out of range) raises
:class:`InputError`, a ``ValueError`` whose ``str`` is one readable line naming the file, key or
argument at fault.  An estimation that cannot succeed on good input (too few fixtures, a
degenerate geometry) does not raise: it returns a result that is falsy and carries the reason
in its ``reason`` field (see docs/conventions.md, "Results and failures").
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError"]


class InputError(ValueError):
    """Bad input: a missing, unreadable or malformed file.  ``str(err)`` is one line."""

    def __init__(self, what: str, source: str | Path | None = None):
        self.what = what
        self.source = str(source) if source is not None else None
        super().__init__(f"{what} ({self.source})" if self.source else what)
