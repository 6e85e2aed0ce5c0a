"""The rolling shutter's readout: which image axis the sensor reads along, and which way.

A :class:`Readout` is a ``str`` (``"rows"``, ``"columns"``, ``"rows-reversed"``,
``"columns-reversed"``), so it compares equal to, prints and serialises as the strings of the
camera file and the command line; it is parsed once, where it enters (a file, an option, a
settings object), and read through its properties everywhere else.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["DEFAULT_ROW_TIME_S", "READOUT_NAMES", "Readout"]

#: Row time (s), the time between the readouts of two sensor rows, assumed where neither a
#: camera file nor an option gives one: the thesis' camera's assumed 20 us (the renderer and
#: the coverage study use it; :mod:`camvlp.model.camera` gives it too).
DEFAULT_ROW_TIME_S = 20e-6

# The readouts along rows and those reversed, by their names: a set's look-up is a few times
# quicker than comparing with the members (read several times a locate).
_BY_ROWS = frozenset({"rows", "rows-reversed"})
_REVERSED = frozenset({"rows-reversed", "columns-reversed"})


class Readout(StrEnum):
    """Which image axis the sensor reads out along, and in which direction.

    ``ROWS``: sensor rows are image rows, read from the top down (stripes horizontal);
    ``COLUMNS``: a photo stored in portrait, sensor rows are image columns read from left to
    right (stripes vertical); ``-reversed``: time runs the other way (bottom up, right to
    left).  Read backwards, some Manchester IDs' frames are other IDs' frames.
    """

    ROWS = "rows"
    COLUMNS = "columns"
    ROWS_REVERSED = "rows-reversed"
    COLUMNS_REVERSED = "columns-reversed"

    @classmethod
    def parse(cls, value: str | Readout, what: str = "readout") -> Readout:
        """The readout named by ``value``.

        Raises
        ------
        ValueError
            One line naming ``what`` and the accepted names.
        """
        try:
            return cls(value)
        except ValueError:
            raise ValueError(
                f"{what} must be rows, columns, rows-reversed or columns-reversed, got {value!r}"
            ) from None

    @classmethod
    def parse_optional(cls, value: str | Readout | None, what: str = "readout") -> Readout | None:
        """:meth:`parse`, passing None through (readout not known)."""
        return None if value is None else cls.parse(value, what)

    @property
    def axis(self) -> str:
        """``"rows"`` or ``"columns"``: the image axis along which exposure times advance."""
        return "rows" if self in _BY_ROWS else "columns"

    @property
    def by_rows(self) -> bool:
        """Sensor rows are image rows (stripes horizontal)."""
        return self in _BY_ROWS

    @property
    def reversed(self) -> bool:
        """Time runs towards the first image row (column): bottom up or right to left."""
        return self in _REVERSED

    @property
    def pixel_index(self) -> int:
        """Index of the readout coordinate in a pixel ``[u, v]``: 1 for rows, 0 for columns."""
        return 1 if self.by_rows else 0

    @property
    def array_axis(self) -> int:
        """Axis of an image array ``(H, W)`` along which time advances: 0 rows, 1 columns."""
        return 0 if self.by_rows else 1

    @classmethod
    def of(cls, axis: str, reversed_: bool = False) -> Readout:
        """The readout along ``axis`` ("rows" or "columns"), forward or reversed."""
        return cls.parse(f"{axis}-reversed" if reversed_ else axis)


#: The accepted names, for help texts and choices.
READOUT_NAMES: tuple[str, ...] = tuple(r.value for r in Readout)
