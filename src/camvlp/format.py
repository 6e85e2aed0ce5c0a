"""How lengths are shown to people: one rule for metres, centimetres and millimetres.

Errors span six decades (a rounding error of 0.2 mm, a forced world error of 1 m), so what a
command prints and what a plot's axis shows pick the unit from the size of the value: metres
from 0.5 m, centimetres from 1 cm, millimetres below.
"""

from __future__ import annotations

import math

from camvlp.model.fixtures import UNITS_TO_M

__all__ = ["format_length", "length_unit", "mm_per_unit"]

#: (smallest value in metres, factor from metres, unit name), largest first.
_UNITS = ((0.5, 1.0, "m"), (0.01, 100.0, "cm"), (0.0, 1000.0, "mm"))
_FACTOR = {unit: factor for _, factor, unit in _UNITS}
_DIGITS = {"m": 3, "cm": 2, "mm": 2}


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
    return f"{value_m * _FACTOR[name]:.{_DIGITS[name]}f} {name}"


def mm_per_unit(units: str) -> tuple[float, str]:
    """Factor from a map's length unit to the unit its errors are shown in, and that unit.

    Millimetres for maps in m, cm or mm; any other unit is shown as it is.
    """
    if units in UNITS_TO_M:
        return UNITS_TO_M[units] * 1000.0, "mm"
    return 1.0, units
