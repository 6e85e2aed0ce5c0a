"""A Griffe extension for the API reference: Sphinx roles in docstrings read as code.

The package's docstrings name other objects the Sphinx way (``:class:`Pose```,
``:func:`~camvlp.io.load_camera```); Markdown would show the role's colons and name. Each role
becomes the name alone, as inline code (``~`` keeps its last part, as Sphinx shows it).
Loaded by mkdocstrings (``mkdocs.yml``, ``extensions``).
"""

from __future__ import annotations

import re
from typing import Any

import griffe

#: ``:role:`target``` or ``:py:role:`~target```.
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|attr|data|mod|obj|exc|const|ref):`(~?)([^`]+)`")


def _as_code(match: re.Match[str]) -> str:
    """The role's target as inline code: its last part when written with ``~``."""
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


class SphinxRolesAsCode(griffe.Extension):
    """Rewrite each object's docstring once it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        """Replace the Sphinx roles of ``obj``'s docstring by inline code."""
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(_as_code, obj.docstring.value)
