"""The line code: frames, Manchester chips, and cyclic decoding (thesis section 5.4).

A fixture repeats its frame without gaps: a preamble (default ``111``), its ID in
``id_bits`` bits (most significant first), optionally ``check_bits`` bits of a cyclic
redundancy check of the ID (:data:`CRC_POLYNOMIALS`; a frame read with an error in it then
fits no ID's frame rather than another's), a postamble (default ``00``).  Each bit is sent
as two chips: bit 0 as chips ``1, 0`` and bit 1 as chips ``0, 1``.  Chip 1 is light on.

Decoding is cyclic: any ``n_chips`` consecutive chips of the repeating stream, starting at
any chip (so in either Manchester phase), identify the ID.  The decoder compares the chips
with every rotation of every ID's chip sequence and accepts the nearest ID only when it is
within the format's guaranteed correction radius and strictly nearer than any other ID, so
it never returns a wrong ID for errors within that radius.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = [
    "CRC_POLYNOMIALS",
    "ChipDecode",
    "FrameFormat",
    "chip_schedule",
    "crc_bits",
    "manchester_encode",
]

#: Most bits a frame may have (preamble + ID + postamble): two chips a bit fit one 64-bit word.
MAX_FRAME_BITS = 32

#: The generator polynomial of the ID's check for each width (bits): x + 1 (parity),
#: x^2 + x + 1, x^3 + x + 1, x^4 + x + 1, x^5 + x^2 + 1, x^6 + x + 1, x^7 + x^3 + 1 and
#: x^8 + x^2 + x + 1, each its coefficients as bits, the highest first.
CRC_POLYNOMIALS = {1: 0b11, 2: 0b111, 3: 0b1011, 4: 0b10011, 5: 0b100101, 6: 0b1000011,
                   7: 0b10001001, 8: 0b100000111}  # fmt: skip


def crc_bits(value: int, n_bits: int, width: int) -> str:
    """The ``width``-bit check (:data:`CRC_POLYNOMIALS`) of ``value``'s ``n_bits`` bits: the
    remainder of ``value * x^width`` divided by the polynomial, as a string of 0 and 1."""
    poly = CRC_POLYNOMIALS[width]
    rem = value << width
    for shift in range(n_bits - 1, -1, -1):
        if rem >> (shift + width) & 1:
            rem ^= poly << shift
    return format(rem, f"0{width}b")


def manchester_encode(bits) -> np.ndarray:
    """Manchester chips of a bit sequence: 0 -> (1, 0), 1 -> (0, 1).

    Parameters
    ----------
    bits : str or array_like of {0, 1}, shape (N,)

    Returns
    -------
    ndarray of uint8, shape (2 N,)
    """
    b = _bits_array(bits)
    chips = np.empty(2 * b.size, dtype=np.uint8)
    chips[0::2] = 1 - b
    chips[1::2] = b
    return chips


def _bits_array(bits) -> np.ndarray:
    if isinstance(bits, str):
        if any(c not in "01" for c in bits):
            raise ValueError(f"bits must be a string of 0 and 1, got {bits!r}")
        return np.frombuffer(bits.encode(), dtype=np.uint8) - ord("0")
    b = np.asarray(bits).reshape(-1)
    if not np.all((b == 0) | (b == 1)):
        raise ValueError("bits must be 0 or 1")
    return b.astype(np.uint8)


def chip_schedule(chips, chip_rate_hz: float) -> list[tuple[int, float]]:
    """The LED's on/off schedule for one frame: runs of equal chips and their durations.

    Parameters
    ----------
    chips : array_like of {0, 1}, shape (N,)
        One frame of chips (1 = light on).
    chip_rate_hz : float
        Chips per second.

    Returns
    -------
    list of (state, duration_s)
        ``state`` is 1 (on) or 0 (off); durations in seconds.  Runs are not merged across the
        frame's wrap-around, so the schedule repeats exactly.
    """
    if not chip_rate_hz > 0:
        raise ValueError(f"chip_rate_hz must be positive, got {chip_rate_hz}")
    c = _bits_array(chips)
    edges = np.flatnonzero(np.diff(c)) + 1
    starts = np.concatenate([[0], edges])
    lengths = np.diff(np.concatenate([starts, [c.size]]))
    return [(int(c[s]), float(n) / chip_rate_hz) for s, n in zip(starts, lengths, strict=True)]


@dataclass(frozen=True)
class ChipDecode:
    """The result of decoding a chip sequence.

    Attributes
    ----------
    id : int or None
        The decoded ID, or None when the chips do not identify one unambiguously.
    distance : int
        Chips that disagree with the decoded (or nearest) ID's stream (Hamming distance).
    runner_up_distance : int
        Hamming distance to the nearest other ID; ``runner_up_distance - distance`` is the
        decision margin in chips.
    offset : int
        Chip index, within the frame, of the first chip given; odd offsets are the other
        Manchester phase.
    reason : str
        Why no ID was returned ("" when one was).
    """

    id: int | None
    distance: int
    runner_up_distance: int
    offset: int
    reason: str = ""

    def __bool__(self) -> bool:
        return self.id is not None


@dataclass(frozen=True)
class FrameFormat:
    """A Manchester frame: preamble, ID bits, postamble (thesis: ``111``, 4, ``00``).

    Raises ValueError when a part is malformed or when two IDs of the format could be
    confused: some rotation of one ID's chip stream equals some rotation of another's.
    """

    preamble: str = "111"
    id_bits: int = 4
    postamble: str = "00"
    check_bits: int = 0

    def __post_init__(self) -> None:
        for name in ("preamble", "postamble"):
            value = getattr(self, name)
            if not isinstance(value, str) or any(c not in "01" for c in value):
                raise ValueError(f"frame {name} must be a string of 0 and 1, got {value!r}")
        if not isinstance(self.id_bits, int) or not 1 <= self.id_bits <= 12:
            raise ValueError(f"frame id_bits must be an integer from 1 to 12, got {self.id_bits!r}")
        if self.check_bits != 0 and self.check_bits not in CRC_POLYNOMIALS:
            raise ValueError(
                f"frame check_bits must be an integer from 0 to {max(CRC_POLYNOMIALS)}, "
                f"got {self.check_bits!r}"
            )
        if self.n_bits > MAX_FRAME_BITS:
            raise ValueError(
                f"frame has {self.n_bits} bits (preamble, id_bits, postamble); at most "
                f"{MAX_FRAME_BITS} are supported"
            )
        if self.min_distance == 0:
            raise ValueError(
                f"frame format {self.preamble}+{self.id_bits} bits"
                + (f"+{self.check_bits} check bits" if self.check_bits else "")
                + f"+{self.postamble} is ambiguous: "
                "a rotation of one ID's frame equals a rotation of another's"
            )

    @property
    def n_ids(self) -> int:
        """Number of IDs the format can carry (``2 ** id_bits``)."""
        return 1 << self.id_bits

    @property
    def n_bits(self) -> int:
        """Bits per frame."""
        return len(self.preamble) + self.id_bits + self.check_bits + len(self.postamble)

    @property
    def n_chips(self) -> int:
        """Chips per frame (two per bit)."""
        return 2 * self.n_bits

    def check_id(self, fixture_id: int) -> int:
        """Return ``fixture_id`` if it fits the format, else raise ValueError."""
        if not isinstance(fixture_id, (int, np.integer)) or isinstance(fixture_id, bool):
            raise ValueError(f"fixture ID must be an integer, got {fixture_id!r}")
        if not 0 <= fixture_id < self.n_ids:
            raise ValueError(
                f"fixture ID {fixture_id} does not fit in {self.id_bits} bits "
                f"(0 to {self.n_ids - 1})"
            )
        return int(fixture_id)

    def bits(self, fixture_id: int) -> str:
        """The frame's bits as a string, e.g. ``'111010100'`` for ID 5."""
        fid = self.check_id(fixture_id)
        check = crc_bits(fid, self.id_bits, self.check_bits) if self.check_bits else ""
        return self.preamble + format(fid, f"0{self.id_bits}b") + check + self.postamble

    def chips(self, fixture_id: int) -> np.ndarray:
        """The frame's Manchester chips, uint8 array of shape (n_chips,)."""
        return manchester_encode(self.bits(fixture_id))

    @cached_property
    def codebook(self) -> np.ndarray:
        """Chips of every ID, uint8 array of shape (n_ids, n_chips)."""
        return np.stack([self.chips(i) for i in range(self.n_ids)])

    @cached_property
    def reversed_ids(self) -> np.ndarray:
        """For each ID, the ID whose frame is its frame read backwards (-1 where none is),
        int64 array of shape (n_ids,): a photo whose readout direction is not known may read
        one as the other.

        The frame read backwards is looked up, as one 64-bit word, among every rotation of
        every ID (:attr:`_packed`, sorted): the ID it equals a rotation of (two IDs' rotations
        never are equal, :attr:`min_distance` being 1 or more)."""
        n = self.n_chips
        packed = self._packed.reshape(-1)
        order = np.argsort(packed, kind="stable")
        words = packed[order]
        backwards = (self.codebook[:, ::-1] * _weights(n)).sum(axis=1, dtype=np.uint64)
        at = np.minimum(np.searchsorted(words, backwards), words.size - 1)
        found = words[at] == backwards
        return np.where(found, order[at] // n, -1).astype(np.int64)

    @cached_property
    def _packed(self) -> np.ndarray:
        """Every rotation of every ID as one 64-bit word (chip ``j`` its bit ``j``), uint64
        array of shape (n_ids, n_chips): ``[i, r]`` the rotation that starts at chip ``r``."""
        n = self.n_chips
        weights = _weights(n)
        idx = (np.arange(n)[:, None] + np.arange(n)[None, :]) % n
        return np.stack(
            [(self.codebook[:, idx[r]] * weights).sum(axis=1, dtype=np.uint64) for r in range(n)],
            axis=1,
        )

    @cached_property
    def _rotations(self) -> np.ndarray:
        """Every rotation of every ID: shape (n_ids, n_chips, n_chips), ``[i, r]`` starts at r."""
        n = self.n_chips
        idx = (np.arange(n)[:, None] + np.arange(n)[None, :]) % n
        return self.codebook[:, idx]

    @cached_property
    def min_distance(self) -> int:
        """Least Hamming distance between any rotations of two different IDs' frames.

        Each rotation is packed into one 64-bit word and the pairs are compared in chunks of
        about four million (XOR and popcount), so memory stays near 100 MB and time near two
        seconds even for 12 ID bits (4096 IDs, 139,264 rotations).
        """
        n, n_ids = self.n_chips, self.n_ids
        packed = self._packed  # (n_ids, n): rotation r of each ID as a word
        ref = packed[:, 0]  # rotation 0 of each ID is enough: distance is rotation-invariant
        owner = np.repeat(np.arange(n_ids), n)
        flat = packed.reshape(-1)
        best = n + 1
        step = max(1, (1 << 22) // flat.size)
        for i0 in range(0, n_ids - 1, step):  # each unordered pair once: j > i
            i1 = min(n_ids - 1, i0 + step)
            later = owner > i0
            d = np.bitwise_count(ref[i0:i1, None] ^ flat[None, later])
            d[owner[None, later] <= np.arange(i0, i1)[:, None]] = n + 1
            best = min(best, int(d.min()))
            if best == 0:
                break
        return best

    def decode(self, chips, *, known=None, max_errors: int | None = None) -> ChipDecode:
        """Decode a stretch of the repeating chip stream cyclically.

        Parameters
        ----------
        chips : array_like of {0, 1}, shape (L,)
            Consecutive chips (1 = light on), starting at any chip of the frame.
        known : array_like of bool, shape (L,), optional
            Which chips were observed with confidence; the others (erasures) are ignored.
            Every chip position of the frame must be known at least once.
        max_errors : int, optional
            Largest Hamming distance accepted.  The default, and the most ever accepted, is
            the radius within which the nearest ID is guaranteed right: with the known chips
            covering every frame position ``k`` times, ``(k * min_distance - 1) // 2``.

        Returns
        -------
        ChipDecode
            Falsy, with a reason, when no ID is within the radius or two IDs tie.
        """
        if isinstance(chips, np.ndarray) and chips.dtype == np.uint8 and chips.ndim == 1:
            c = chips  # the stripe decoder's chips: checked with one reduction
            if c.size and c.max() > 1:
                raise ValueError("bits must be 0 or 1")
        else:
            c = _bits_array(chips)
        mask = None if known is None else np.asarray(known, bool).reshape(-1)
        if mask is not None and mask.shape != c.shape:
            raise ValueError("known must have the same length as chips")
        return self.decode_many([(c, mask)], max_errors=max_errors)[0]

    def decode_many(self, stretches, *, max_errors: int | None = None) -> list[ChipDecode]:
        """:meth:`decode` of several stretches at once.

        The distances from every rotation of every ID are counted for all stretches in one
        matrix product (:meth:`stretch_distances`), so the cost does not grow with the
        stretches' lengths.

        Parameters
        ----------
        stretches : sequence of (chips, known)
            ``chips`` a uint8 array of 0 and 1, shape (L,); ``known`` a bool array of the same
            shape, or None when every chip is known.
        max_errors : int, optional
            As in :meth:`decode`, for every stretch.

        Returns
        -------
        list of ChipDecode
            One per stretch, as :meth:`decode` gives it.
        """
        n = self.n_chips
        if len(stretches) == 0:
            return []
        dist, seen = self._distances(stretches)
        m = dist.shape[0]
        coverage = seen.min(axis=1)
        limit = (coverage * self.min_distance - 1) // 2
        if max_errors is not None:
            limit = np.minimum(limit, int(max_errors))
        per_id = dist.min(axis=2)
        best = per_id.argmin(axis=1)  # the first of the nearest, as a stable sort's
        rows = np.arange(m)
        offset = dist[rows, best].argmin(axis=1)
        n_seen = seen.sum(axis=1)
        d_best = per_id[rows, best]
        if self.n_ids > 1:  # the next: an ID as near, or the nearest other
            per_id[rows, best] = _INT64_MAX  # (the nearest left out)
            d_second = per_id.min(axis=1)
        else:
            d_second = n_seen + 1
        return [
            _chip_decode(*v, n)
            for v in zip(
                *(a.tolist() for a in (best, d_best, d_second, offset, coverage, limit, n_seen)),
                strict=True,
            )
        ]

    def stretch_distances(self, stretches) -> np.ndarray:
        """Each stretch's distance from every rotation of every ID's frame.

        Parameters
        ----------
        stretches : sequence of (chips, known)
            As :meth:`decode_many` takes them; a stretch shorter than a frame is met by the
            first chips of each rotation.

        Returns
        -------
        ndarray of int64, shape (m, n_ids, n_chips)
            ``[s, i, r]``: the known chips of stretch ``s`` that disagree with ID ``i``'s
            stream started at chip ``r`` of its frame (its chip ``j`` met by frame chip
            ``(r + j) mod n_chips``).
        """
        if len(stretches) == 0:
            return np.zeros((0, self.n_ids, self.n_chips), np.int64)
        return self._distances(stretches)[0]

    def _distances(self, stretches) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`stretch_distances` (one or more stretches), and how many known chips each
        stretch has at each position of the frame (m, n_chips).

        Each chip position's mismatches with every rotation of every ID are counted in one
        matrix product for all stretches: a stretch's known chips are summed per position
        of the frame (a chip ``j`` meets chip ``j mod n`` of each rotation), so the cost
        does not grow with the stretches' lengths."""
        n, n_ids = self.n_chips, self.n_ids
        m = len(stretches)
        sizes = [c.size for c, _ in stretches]
        width = -(-max(sizes) // n) * n if max(sizes) > 0 else n  # whole frames
        k = np.zeros((m, width), bool)
        on = np.zeros((m, width), bool)
        for k_row, on_row, (ch, kn) in zip(k, on, stretches, strict=True):  # (a few stretches)
            k_row[: ch.size] = True if kn is None else kn
            on_row[: ch.size] = ch
        on &= k
        # per stretch and frame position: known chips, and known ones
        seen = k.reshape(m, -1, n).sum(axis=1, dtype=np.intp)  # (m, n)
        ones = on.reshape(m, -1, n).sum(axis=1, dtype=np.intp)
        # distances (m, n_ids, n): what a rotation's chip 1 adds to the distance (one chip 0
        # more that disagrees, one chip 1 fewer), on top of the known ones; exact, every sum
        # a whole number below 2**24
        weight = (seen - 2 * ones).astype(np.float32)
        dist = (weight @ self._rotations_by_chip).astype(np.int64)
        dist += ones.sum(axis=1)[:, None]
        return dist.reshape(m, n_ids, n), seen

    @cached_property
    def _rotations_by_chip(self) -> np.ndarray:
        """:attr:`_rotations` as float32, one column per ID and rotation (n_chips,
        n_ids * n_chips): :meth:`decode_many`'s matrix product's right-hand side."""
        r = np.ascontiguousarray(self._rotations.astype(np.float32).reshape(-1, self.n_chips).T)
        r.flags.writeable = False
        return r


def _weights(n: int) -> np.ndarray:
    """Each of ``n`` chips' bit in a 64-bit word, uint64 array of shape (n,)."""
    return np.left_shift(np.uint64(1), np.arange(n, dtype=np.uint64))


#: The largest int64 (``np.iinfo`` builds an object each time it is called).
_INT64_MAX = np.iinfo(np.int64).max


def _chip_decode(
    best: int, d_best: int, d_second: int, offset: int, coverage: int, limit: int, seen: int, n: int
) -> ChipDecode:
    """One stretch's :class:`ChipDecode` from its distances (see :meth:`FrameFormat.decode`)."""
    if coverage == 0:
        return ChipDecode(None, -1, -1, 0, f"{seen} chips seen, not one whole frame of {n}")
    if d_best == d_second:
        return ChipDecode(None, d_best, d_second, offset, "two IDs fit equally well")
    if d_best > limit:
        return ChipDecode(
            None,
            d_best,
            d_second,
            offset,
            f"{d_best} chips disagree with the nearest ID (at most {limit} correctable)",
        )
    return ChipDecode(best, d_best, d_second, offset)
