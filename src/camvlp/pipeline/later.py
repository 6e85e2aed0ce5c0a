"""Values of a frozen dataclass worked out when first read.

Some of what a photo's results carry costs more to work out than most callers ever read: the
centres' covariances (:attr:`camvlp.pipeline.detect.refine.Blob.centre_cov_px2`) take a tenth of a
1080p photo's :func:`~camvlp.pipeline.locate.locate` and are read only to tell look-alikes
apart, with gravity, or when the result is shown.  Such a field is a :class:`LaterField`:
it is given either its value or a :class:`Later` (a function and its arguments), which is
called the first time the field is read and replaced by what it returns.  ``==``, ``repr``
and ``dataclasses.replace`` read the field as any other, and so work it out;
:func:`replaced` is ``dataclasses.replace`` that carries a field still to be worked out over
as it is.  Pickling keeps it as it is (a :class:`Later` pickles when its function does).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

__all__ = ["Later", "LaterField", "later_of", "replaced"]


class Later:
    """A value still to be worked out: ``fn(*args)``, called when first read.

    Picklable when ``fn`` and ``args`` are (a module-level function, a bound method of a
    picklable object, :func:`operator.attrgetter`, ...).
    """

    __slots__ = ("args", "fn")

    def __init__(self, fn: Callable[..., Any], *args: Any) -> None:
        self.fn, self.args = fn, args

    def __call__(self) -> Any:
        return self.fn(*self.args)

    def __reduce__(self):
        return Later, (self.fn, *self.args)


class LaterField:
    """A dataclass field (the class attribute's default) that takes a value or a
    :class:`Later` and gives the value: the first read of a :class:`Later` calls it and keeps
    what it returns.

    ``default`` is what the field is when not given (None, or a value that cannot change);
    ``missing``, when given, is called for the value read when the field holds None (e.g. a
    fresh array of NaN, which a dataclass may not take as a default).  Works in frozen
    dataclasses: the value is kept in the instance's ``__dict__`` under ``_`` + its name.
    """

    def __init__(self, default: Any = None, missing: Callable[[], Any] | None = None) -> None:
        self.default, self.missing = default, missing
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = "_" + name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:  # the class' attribute: the dataclass' default
            return self.default
        value = obj.__dict__.get(self.name, self.default)
        if isinstance(value, Later):
            value = value()
            obj.__dict__[self.name] = value
        if value is None and self.missing is not None:
            return self.missing()
        return value

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.name] = value


def later_of(obj: Any, name: str, fn: Callable[[Any], Any]) -> Any:
    """``fn`` of the :class:`LaterField` ``name`` of ``obj``: worked out now when the field
    holds its value, else a :class:`Later` that reads the field's own :class:`Later` (not
    ``obj``, which it does not keep) when first read."""
    value = obj.__dict__.get("_" + name)
    if isinstance(value, Later):
        return Later(_applied, fn, value)
    return fn(getattr(obj, name))


def _applied(fn: Callable[[Any], Any], later: Later) -> Any:
    return fn(later())


def replaced(obj: Any, **changes: Any) -> Any:
    """``dataclasses.replace(obj, **changes)`` without working out the :class:`LaterField`
    fields not changed: one still to be worked out is carried over as its :class:`Later`
    (``dataclasses.replace`` reads every field it is not given, which would call it)."""
    for f in dataclasses.fields(obj):
        if f.init and f.name not in changes:
            value = obj.__dict__.get("_" + f.name)
            if isinstance(value, Later):
                changes[f.name] = value
    return dataclasses.replace(obj, **changes)
