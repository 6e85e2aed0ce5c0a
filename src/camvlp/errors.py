"""The package's error for bad input, and its result convention.

Bad input (a missing, unreadable or malformed file or array, an option out of range) raises
:class:`InputError`, a ``ValueError`` whose ``str`` is one readable line naming the file, key or
argument at fault.  An estimation that cannot succeed on good input (too few fixtures, a
degenerate geometry) does not raise: it returns a result that is falsy and carries the reason
in its ``reason`` field (see docs/conventions.md, "Results and failures").
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError", "one_line"]


def one_line(text: str) -> str:
    """``text`` with every unprintable character (newline, tab, escape ...) written as its
    backslash escape, so a message or a file name can never split or colour a line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class InputError(ValueError):
    """Bad input: a missing, unreadable or malformed file.  ``str(err)`` is one line."""

    def __init__(self, what: str, source: str | Path | None = None):
        self.what = one_line(str(what))
        self.source = one_line(str(source)) if source is not None else None
        super().__init__(f"{self.what} ({self.source})" if self.source else self.what)
