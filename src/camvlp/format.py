"""How figures are shown to people: no negative zero, one rule for metres, centimetres and
millimetres.

A figure that rounds to zero shows as ``0.00``, never ``-0.00`` (:func:`format_number`, for
every number a command prints).  Errors span six decades (a rounding error of 0.2 mm, a forced
world error of 1 m), so what a command prints and what a plot's axis shows pick the unit from
the size of the value: metres from 0.5 m, centimetres from 1 cm, millimetres below.
"""

from __future__ import annotations

import math
from numbers import Integral

import numpy as np

__all__ = [
    "UNITS_TO_M",
    "format_length",
    "format_number",
    "format_vector",
    "length_unit",
    "mm_per_unit",
]

#: Length units a map may use, and their size in metres.
UNITS_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}

#: (smallest value in metres, factor from metres, unit name), largest first.
_UNITS = ((0.5, 1.0, "m"), (0.01, 100.0, "cm"), (0.0, 1000.0, "mm"))
_FACTOR = {unit: factor for _, factor, unit in _UNITS}
_DIGITS = {"m": 3, "cm": 2, "mm": 2}


def format_number(value: float, spec: str = "") -> str:
    """``format(value, spec)``, except that a value which shows as zero has no minus sign.

    ``format(-0.0001, ".2f")`` is ``"-0.00"``: a pose at the origin prints ``-0.0000`` for half
    its coordinates.  Here it is ``"0.00"``, as ``format(0.0, spec)`` (same width and sign
    option); a value that does not round to zero keeps its sign (``-0.01``).
    """
    if isinstance(value, Integral) or math.copysign(1.0, value) > 0:  # no negative zero
        return format(value, spec)
    zero = format(0.0, spec)
    return zero if format(-value, spec) == zero else format(value, spec)


def format_vector(values) -> str:
    """A vector as text for a message, each number in ``g`` format: ``"(0.59, -2.88, -9.36)"``.

    Parameters
    ----------
    values : array_like
        Any shape (flattened), any units.
    """
    return "(" + ", ".join(f"{x:g}" for x in np.asarray(values, float).reshape(-1)) + ")"


def length_unit(largest_m: float) -> tuple[float, str]:
    """The factor from metres and the unit name to show lengths up to ``largest_m`` in.

    Metres from 0.5 m, centimetres from 1 cm, millimetres below (and for NaN).
    """
    for lo, factor, unit in _UNITS:
        if largest_m >= lo:
            return factor, unit
    return 1000.0, "mm"


def format_length(value_m: float | None, unit: str | None = None) -> str:
    """A length in metres as text with its unit, e.g. ``"1.23 mm"``; ``"n/a"`` for None or NaN.

    Parameters
    ----------
    value_m : float or None
        Length, metres.
    unit : {"m", "cm", "mm"}, optional
        Force a unit; default :func:`length_unit` of the value.
    """
    if value_m is None or not math.isfinite(value_m):
        return "n/a"
    name = unit or length_unit(abs(value_m))[1]
    return f"{format_number(value_m * _FACTOR[name], f'.{_DIGITS[name]}f')} {name}"


def mm_per_unit(units: str) -> tuple[float, str]:
    """Factor from a map's length unit to the unit its errors are shown in, and that unit.

    Millimetres for maps in m, cm or mm; any other unit is shown as it is.
    """
    if units in UNITS_TO_M:
        return UNITS_TO_M[units] * 1000.0, "mm"
    return 1.0, units
