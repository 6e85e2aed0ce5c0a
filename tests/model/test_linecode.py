"""Tests for the line code: frames, Manchester chips, the LED schedule and cyclic decoding.

The decode tests are exhaustive in the AprilTag manner: every ID of the default format, every
starting chip, every single flipped chip, and every pair of flipped chips where the format
guarantees a correction.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from camvlp.model.linecode import FrameFormat, chip_schedule, manchester_encode

FMT = FrameFormat()
N_CHIPS = 18
#: Window lengths in chips: one frame, 1.2, 2 and 3 frames.
WINDOWS = {"1": 18, "1.2": 22, "2": 36, "3": 54}


def _window(fid: int, start: int, length: int) -> np.ndarray:
    """``length`` chips of ID ``fid``'s repeating stream, starting at chip ``start``."""
    stream = np.tile(FMT.chips(fid), math.ceil((start + length) / N_CHIPS))
    return stream[start : start + length].copy()


def _flipped(chips: np.ndarray, positions) -> np.ndarray:
    out = chips.copy()
    out[list(positions)] ^= 1
    return out


def _radius(coverage: int) -> int:
    """Correction radius the decoder promises with every frame position seen ``coverage`` times."""
    return (coverage * FMT.min_distance - 1) // 2


# --- encoding -------------------------------------------------------------------------------


def test_manchester_encode_follows_the_thesis_polarity():
    # thesis 5.4: 0 -> 1-0, 1 -> 0-1
    assert manchester_encode("01").tolist() == [1, 0, 0, 1]
    assert manchester_encode([1, 1, 0]).tolist() == [0, 1, 0, 1, 1, 0]
    assert manchester_encode("").tolist() == []
    with pytest.raises(ValueError, match="bits"):
        manchester_encode("012")
    with pytest.raises(ValueError, match="bits"):
        manchester_encode([0, 2])


def test_id_5_frame_bits_and_chips_by_hand():
    # preamble 111, ID 5 = 0101 (MSB first), postamble 00
    assert FMT.bits(5) == "111" + "0101" + "00" == "111010100"
    # 1->01 1->01 1->01 0->10 1->01 0->10 1->01 0->10 0->10
    by_hand = "".join(["01", "01", "01", "10", "01", "10", "01", "10", "10"])
    assert by_hand == "010101100110011010"
    assert "".join(map(str, FMT.chips(5))) == by_hand
    assert FMT.n_bits == 9 and FMT.n_chips == N_CHIPS and FMT.n_ids == 16


def test_codebook_rows_are_the_chips_of_each_id():
    book = FMT.codebook
    assert book.shape == (16, N_CHIPS)
    for fid in range(16):
        assert book[fid].tolist() == FMT.chips(fid).tolist()
        assert FMT.bits(fid)[3:7] == format(fid, "04b")
    # Manchester: every bit is one 0 and one 1, so every frame is balanced (constant mean light)
    assert np.all(book.sum(axis=1) == 9)


def test_min_distance_matches_brute_force_over_string_rotations():
    def rotations(s: str) -> list[str]:
        return [s[r:] + s[:r] for r in range(len(s))]

    def brute_force(fmt: FrameFormat) -> int:
        words = ["".join(map(str, fmt.chips(i))) for i in range(fmt.n_ids)]
        return min(
            sum(x != y for x, y in zip(words[i], rot, strict=True))
            for i, j in itertools.combinations(range(fmt.n_ids), 2)
            for rot in rotations(words[j])
        )

    # two IDs one bit apart differ in exactly two chips, so 2 is the most a 4-bit ID allows
    assert brute_force(FMT) == FMT.min_distance == 2
    other = FrameFormat("1110", 3, "0")
    assert brute_force(other) == other.min_distance


# --- format validation ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("1", 4, "0"), "ambiguous"),
        (("", 2, ""), "ambiguous"),
        (("111", 6, "00"), "ambiguous"),
        (("112", 4, "00"), "preamble"),
        ((111, 4, "00"), "preamble"),
        (("111", 4, "0a"), "postamble"),
        (("111", 0, "00"), "id_bits"),
        (("111", 13, "00"), "id_bits"),
        (("111", 4.0, "00"), "id_bits"),
    ],
)
def test_frame_format_rejects_malformed_or_ambiguous_formats(args, message):
    with pytest.raises(ValueError, match=message):
        FrameFormat(*args)


def test_ambiguous_example_really_is_ambiguous():
    # preamble 1, 4 bits, postamble 0: ID 1 sends 1 0001 0 and ID 4 sends 1 0100 0, which is
    # the same cycle read from its fifth bit on
    a, b = "1" + "0001" + "0", "1" + "0100" + "0"
    assert b == a[4:] + a[:4]


@pytest.mark.parametrize("bad", [16, -1, 100, True, 2.0, "5"])
def test_ids_outside_the_format_are_rejected(bad):
    with pytest.raises(ValueError, match="fixture ID"):
        FMT.bits(bad)
    with pytest.raises(ValueError, match="fixture ID"):
        FMT.chips(bad)


def test_ids_fit_wider_formats():
    # not ("111", 6, "00"): ID 7 sends 111 000111 00, a rotation of ID 14's 111 001110 00
    wide = FrameFormat("111", 6, "000")
    assert wide.bits(63) == "111" + "111111" + "000"
    with pytest.raises(ValueError, match="6 bits"):
        wide.bits(64)


# --- the LED schedule -----------------------------------------------------------------------


def test_chip_schedule_of_id_5_by_hand():
    # chips 0 1 0 1 0 11 00 11 00 11 0 1 0 at 10 kHz: runs of 1 or 2 chips of 100 us
    runs = [(0, 1), (1, 1), (0, 1), (1, 1), (0, 1), (1, 2), (0, 2), (1, 2), (0, 2), (1, 2),
            (0, 1), (1, 1), (0, 1)]  # fmt: skip
    got = chip_schedule(FMT.chips(5), 10_000.0)
    assert [s for s, _ in got] == [s for s, _ in runs]
    np.testing.assert_allclose([d for _, d in got], [n * 1e-4 for _, n in runs])


@pytest.mark.parametrize("rate", [1_000.0, 10_000.0, 37_500.0])
def test_chip_schedule_sums_to_the_frame_and_alternates(rate):
    for fid in range(16):
        chips = FMT.chips(fid)
        sched = chip_schedule(chips, rate)
        states = [s for s, _ in sched]
        durations = np.array([d for _, d in sched])
        assert sum(durations) == pytest.approx(N_CHIPS / rate, rel=1e-12)
        assert all(a != b for a, b in itertools.pairwise(states))
        assert states[0] == chips[0]
        # Manchester never holds a level longer than two chips
        assert np.all((durations > 0.5 / rate) & (durations < 2.5 / rate))
        # expanding the schedule gives back the chips
        expanded = np.concatenate([np.full(round(d * rate), s) for s, d in sched])
        assert expanded.tolist() == chips.tolist()


def test_chip_schedule_rejects_bad_rates():
    for rate in (0.0, -5.0, float("nan")):
        with pytest.raises(ValueError, match="chip_rate_hz"):
            chip_schedule(FMT.chips(5), rate)


# --- decoding: exhaustive -------------------------------------------------------------------


@pytest.mark.parametrize("frames", list(WINDOWS))
def test_decode_every_id_at_every_start(frames):
    length = WINDOWS[frames]
    for fid in range(16):
        for start in range(N_CHIPS):
            res = FMT.decode(_window(fid, start, length))
            assert res.id == fid, (fid, start, res)
            assert res.distance == 0 and res.offset == start and res.reason == ""
            assert res.runner_up_distance >= (length // N_CHIPS) * FMT.min_distance
            assert bool(res)


@pytest.mark.parametrize("frames", ["1", "1.2"])
def test_single_flip_in_one_frame_never_gives_a_wrong_id(frames):
    # every frame position is covered once: radius (1 * 2 - 1) // 2 = 0, so a flipped chip is
    # detected (None) but never decoded as another ID
    length = WINDOWS[frames]
    assert _radius(1) == 0
    for fid in range(16):
        for start in range(N_CHIPS):
            clean = _window(fid, start, length)
            for pos in range(length):
                res = FMT.decode(_flipped(clean, [pos]))
                assert res.id in (fid, None), (fid, start, pos, res)
                assert res.id is None and res.reason


@pytest.mark.parametrize("frames", ["2", "3"])
def test_single_flip_in_two_or_more_frames_is_corrected(frames):
    length = WINDOWS[frames]
    assert _radius(length // N_CHIPS) >= 1
    for fid in range(16):
        for start in range(N_CHIPS):
            clean = _window(fid, start, length)
            for pos in range(length):
                res = FMT.decode(_flipped(clean, [pos]))
                assert res.id == fid, (fid, start, pos, res)
                assert res.distance == 1 and res.offset == start


# A window of whole frames starting at chip s is the window starting at chip 0 rotated by s
# (cyclically, over the window), and the decoder tries every rotation: so every pair of flips
# at every start is already every pair of flips at start 0.  Starts 0 and 1 (both Manchester
# phases) are tested to keep the run short.
@pytest.mark.parametrize("start", [0, 1])
def test_every_pair_of_flips_in_three_frames_is_corrected(start):
    length = WINDOWS["3"]
    assert _radius(3) == 2
    for fid in range(16):
        clean = _window(fid, start, length)
        for pair in itertools.combinations(range(length), 2):
            res = FMT.decode(_flipped(clean, pair))
            assert res.id == fid, (fid, pair, res)
            assert res.distance == 2


@pytest.mark.parametrize("start", [0, 1])
def test_every_pair_of_flips_in_two_frames_never_gives_a_wrong_id(start):
    length = WINDOWS["2"]
    assert _radius(2) == 1
    for fid in range(16):
        clean = _window(fid, start, length)
        for pair in itertools.combinations(range(length), 2):
            res = FMT.decode(_flipped(clean, pair))
            assert res.id in (fid, None), (fid, pair, res)


def test_pairs_of_flips_within_one_frame_can_fool_the_code():
    # The reason for the radius: with min_distance 2 two flips can turn one ID into another,
    # so the decoder must not accept them.  ID 5 = 0101 and ID 4 = 0100 differ in two chips.
    five, four = FMT.chips(5), FMT.chips(4)
    diff = np.flatnonzero(five != four)
    assert len(diff) == 2
    res = FMT.decode(_flipped(five, diff))
    assert res.id == 4  # exactly ID 4's frame: indistinguishable, and correctly so
    one = FMT.decode(_flipped(five, diff[:1]))  # halfway: a tie, refused
    assert one.id is None and "equally" in one.reason


# --- decoding: erasures and limits ----------------------------------------------------------


def test_erased_chips_are_ignored():
    rng = np.random.default_rng(11)
    for fid in range(16):
        for start in range(N_CHIPS):
            chips = _window(fid, start, 36)
            known = np.ones(36, bool)
            known[18:] = False  # the second frame is erased: garbage there must not matter
            chips[18:] = rng.integers(0, 2, 18)
            res = FMT.decode(chips, known=known)
            assert res.id == fid and res.distance == 0 and res.offset == start


def test_erasures_lower_the_radius_by_the_coverage():
    rng = np.random.default_rng(12)
    for fid in range(16):
        start = int(rng.integers(N_CHIPS))
        chips = _window(fid, start, 54)
        known = np.ones(54, bool)
        erased = rng.choice(54, 10, replace=False)
        erased = erased[erased < 18]  # only from the first frame: coverage stays >= 2
        known[erased] = False
        chips[erased] ^= 1
        flip = int(rng.integers(18, 54))
        res = FMT.decode(_flipped(chips, [flip]), known=known)
        assert res.id == fid  # coverage 2: radius 1
    # with one frame position never seen, nothing can be promised
    chips = _window(5, 0, 18)
    known = np.ones(18, bool)
    known[7] = False
    res = FMT.decode(chips, known=known)
    assert res.id is None and "not one whole frame" in res.reason


def test_decode_refuses_short_windows_and_checks_the_mask():
    assert FMT.decode(_window(9, 3, 17)).id is None
    assert FMT.decode([]).id is None
    with pytest.raises(ValueError, match="known"):
        FMT.decode(_window(9, 3, 18), known=np.ones(17, bool))
    with pytest.raises(ValueError, match="bits"):
        FMT.decode([0, 1, 2] * 6)


def test_max_errors_only_tightens_the_radius():
    noisy = _flipped(_window(6, 4, 54), [0, 30])
    assert FMT.decode(noisy).id == 6
    tight = FMT.decode(noisy, max_errors=1)
    assert tight.id is None and "at most 1" in tight.reason
    # asking for more than the guarantee gives no more
    one_frame = _flipped(_window(6, 4, 18), [3])
    assert FMT.decode(one_frame, max_errors=5).id is None


def test_decode_many_gives_the_distances_counted_chip_by_chip():
    # stretches of every length, with flips and erasures, decoded together: each one's
    # nearest ID, distance, runner-up and offset as counted against every rotation by hand
    rng = np.random.default_rng(8)
    stretches = []
    for _ in range(80):
        length = int(rng.integers(0, 70))
        chips = _flipped(_window(int(rng.integers(16)), int(rng.integers(18)), length), [])
        chips[rng.random(length) < 0.1] ^= 1
        known = None if rng.random() < 0.3 else rng.random(length) > 0.15
        stretches.append((chips, known))
    got = FMT.decode_many(stretches)
    for (chips, known), res in zip(stretches, got, strict=True):
        k = np.ones(chips.size, bool) if known is None else known
        cols = np.arange(chips.size) % N_CHIPS
        dist = np.array(
            [
                [int(np.sum(k & (FMT.chips(i)[(cols + r) % N_CHIPS] != chips))) for r in range(18)]
                for i in range(16)
            ]
        )
        coverage = int(np.bincount(cols[k], minlength=N_CHIPS).min()) if k.any() else 0
        if coverage == 0:
            assert res.id is None and res.distance == -1
            continue
        best = int(dist.min(axis=1).argmin())
        second = int(np.delete(dist.min(axis=1), best).min())
        assert (res.distance, res.runner_up_distance) == (int(dist[best].min()), second)
        assert res.offset == int(dist[best].argmin())
        ok = second > dist[best].min() and dist[best].min() <= _radius(coverage)
        assert res.id == (best if ok else None)
        assert FMT.decode(chips, known=known) == res


def test_stretch_distances_are_counted_chip_by_chip():
    # shorter and longer than a frame, with erasures: the distance from every rotation of
    # every ID, each chip j met by chip (r + j) mod n of the frame
    rng = np.random.default_rng(9)
    stretches = []
    for length in (5, 11, 18, 31):
        chips = rng.integers(0, 2, length).astype(np.uint8)
        stretches.append((chips, None if length == 11 else rng.random(length) > 0.2))
    got = FMT.stretch_distances(stretches)
    assert got.shape == (4, 16, N_CHIPS)
    for (chips, known), d in zip(stretches, got, strict=True):
        k = np.ones(chips.size, bool) if known is None else known
        cols = np.arange(chips.size)
        want = [
            [int(np.sum(k & (FMT.chips(i)[(cols + r) % N_CHIPS] != chips))) for r in range(18)]
            for i in range(16)
        ]
        np.testing.assert_array_equal(d, want)
    assert FMT.stretch_distances([]).shape == (0, 16, N_CHIPS)


@pytest.mark.parametrize(
    "frame",
    [FrameFormat(), FrameFormat("111", 5, "00"), FrameFormat("1111", 4, "000", 3)],
    ids=str,
)
def test_reversed_ids_are_the_frames_read_backwards(frame):
    # each ID's frame read backwards decoded with no error allowed, one at a time
    want = [
        -1 if (d := frame.decode(frame.codebook[i][::-1], max_errors=0)).id is None else d.id
        for i in range(frame.n_ids)
    ]
    assert frame.reversed_ids.tolist() == want
