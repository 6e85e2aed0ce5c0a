"""Old module paths of the flat package, kept importable with a DeprecationWarning.

camvlp used to be one flat package (``camvlp.study``, ``camvlp.simulate``, ...).  The modules
now live in sub-packages; ``import camvlp.study`` still works and gives the module at its new
home (the same object, so monkeypatching either name patches both), with a warning that names
the new path.  ``camvlp.locate`` is the public function; ``import camvlp.locate`` (the module
path) keeps working without a warning for ``from camvlp.locate import LocateResult``.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

MOVED: dict[str, str] = {
    "camvlp.camera": "camvlp.model.camera",
    "camvlp.fixtures": "camvlp.model.fixtures",
    "camvlp.linecode": "camvlp.model.linecode",
    "camvlp.detect": "camvlp.pipeline.detect.candidates",
    "camvlp.stripes": "camvlp.imaging.stripe_period",
    "camvlp.decode": "camvlp.pipeline.decode.runs",
    "camvlp.frequency": "camvlp.pipeline.decode.frequency",
    "camvlp.pose": "camvlp.geometry.pose",
    "camvlp.pnp": "camvlp.geometry.pnp",
    "camvlp.simulate": "camvlp.sim.render",
    "camvlp.survey": "camvlp.sim.survey",
    "camvlp.study": "camvlp.analysis.study",
    "camvlp.evaluate": "camvlp.analysis.evaluate",
    "camvlp.calibrate": "camvlp.analysis.calibrate",
    "camvlp.annotate": "camvlp.viz.annotate",
}


class _AliasLoader(importlib.abc.Loader):
    def __init__(self, new: str):
        self.new = new

    def create_module(self, spec):  # type: ignore[override]
        warnings.warn(
            f"{spec.name} has moved to {self.new}; import it from there",
            DeprecationWarning,
            stacklevel=3,
        )
        return importlib.import_module(self.new)

    def exec_module(self, module) -> None:  # already executed at its new home
        pass


class _AliasFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):  # type: ignore[override]
        new = MOVED.get(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _AliasLoader(new))


def install() -> None:
    """Make the old module paths importable (idempotent)."""
    if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
    # The module path camvlp.locate: the module of the function camvlp.locate.  Registered
    # directly so that importing it never rebinds the package attribute (the function).
    sys.modules.setdefault("camvlp.locate", importlib.import_module("camvlp.pipeline.locate"))


def forward_moved_names(module: str, moved: dict[str, str]):
    """A module ``__getattr__`` for names that have moved to other modules.

    ``moved`` maps each old name of ``module`` to the object's new dotted path; reading the
    old name returns the object from its new home, with a DeprecationWarning naming it.  Use
    as ``__getattr__ = forward_moved_names(__name__, {"plot_rounding":
    "camvlp.viz.study_plots.plot_rounding"})``.
    """

    def __getattr__(name: str):
        new = moved.get(name)
        if new is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(
            f"{module}.{name} has moved to {new}; import it from there",
            DeprecationWarning,
            stacklevel=2,
        )
        home, attr = new.rsplit(".", 1)
        return getattr(importlib.import_module(home), attr)

    return __getattr__
