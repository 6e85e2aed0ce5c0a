"""Tests of the decoding stage on synthetic row profiles built from the frame's chips.

A profile is made the way a rolling-shutter sensor makes it: the LED's chip stream is
sampled finely in time, bright runs are widened by the bleeding of a saturated sensor, each
row averages its own stretch of time (so edges fall between rows), then optical blur and
noise are added.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.decode import chips as chips_mod
from camvlp.pipeline.decode.chips import bleeds, chip_lengths
from camvlp.pipeline.decode.profile import _nonzero, row_profile, shape_profile
from camvlp.pipeline.decode.run_decode import decode_profile, decode_profiles
from camvlp.pipeline.decode.runs import find_runs, flat_runs, stripe_levels_many

FRAME = FrameFormat()  # preamble 111, 4 ID bits, postamble 00: 18 chips
SUB = 20  # time samples per row


def synth_profile(
    chips: np.ndarray,
    n_rows: int,
    rows_per_chip: float,
    phase_chips: float = 0.0,
    *,
    bleed_rows: float = 0.0,
    blur_rows: float = 0.0,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
    repeat: bool = True,
    dark: float = 20.0,
    bright: float = 220.0,
) -> np.ndarray:
    """Row profile of a chip stream (1 = on) seen ``rows_per_chip`` rows per chip.

    ``phase_chips`` is the chip (fractional) at the top of row 0; ``bleed_rows`` widens each
    bright run by that many rows (half on each side); ``repeat`` repeats the chips cyclically,
    else the stream is ``chips`` once (held at its ends).
    """
    t = (np.arange(n_rows * SUB) + 0.5) / SUB  # rows
    k = np.floor(t / rows_per_chip + phase_chips).astype(int)
    k = k % chips.size if repeat else np.clip(k, 0, chips.size - 1)
    on = chips[k].astype(float)
    widen = round(bleed_rows * SUB)
    if widen > 0:
        on = maximum_filter1d(on, size=widen + 1)
    row = on.reshape(n_rows, SUB).mean(axis=1)
    if blur_rows > 0:
        row = gaussian_filter1d(row, blur_rows, mode="nearest")
    p = dark + (bright - dark) * row
    if noise > 0:
        p = p + noise * rng.standard_normal(p.size)
    return p


def random_case(rng: np.random.Generator) -> dict:
    """Random decodable conditions: 3-8 rows per chip, 1.2-2.5 frames, bleeding, blur, noise."""
    rpc = rng.uniform(3.0, 8.0)
    frames = rng.uniform(1.2, 2.5)
    return dict(
        n_rows=int(frames * FRAME.n_chips * rpc),
        rows_per_chip=rpc,
        phase_chips=rng.uniform(0.0, FRAME.n_chips),
        bleed_rows=rng.uniform(0.0, 0.4 * rpc),
        blur_rows=rng.uniform(0.0, 0.8),
        noise=rng.uniform(0.0, 4.0),
    )


@pytest.mark.parametrize("fid", range(16))
def test_every_id_decodes_under_bleeding_blur_and_noise(fid):
    rng = np.random.default_rng(1000 + fid)
    for _ in range(25):
        case = random_case(rng)
        p = synth_profile(FRAME.chips(fid), rng=rng, **case)
        dec = decode_profile(p, FRAME)
        assert dec.id == fid, (case, dec)
        assert bool(dec)
        assert dec.reason == ""
        assert dec.rows_per_chip == pytest.approx(case["rows_per_chip"], rel=0.02)
        assert 0.0 <= dec.run_margin <= 1.0
        assert dec.frames >= 1.0


def test_never_a_wrong_id_when_the_profile_is_too_short_or_too_noisy():
    """Beyond the limits (less than 1.2 frames, heavy noise) an ID may be missing, never wrong."""
    rng = np.random.default_rng(7)
    missing = 0
    for fid in range(16):
        for _ in range(12):
            case = random_case(rng)
            case["n_rows"] = int(rng.uniform(0.9, 1.2) * FRAME.n_chips * case["rows_per_chip"])
            case["noise"] = rng.uniform(0.0, 25.0)
            dec = decode_profile(synth_profile(FRAME.chips(fid), rng=rng, **case), FRAME)
            assert dec.id in (None, fid), (fid, case, dec)
            if dec.id is None:
                missing += 1
                assert dec.reason
    assert missing < 16 * 12  # the test exercises decoding, not only refusals


def test_exact_chip_length_and_no_bleeding_on_a_clean_profile():
    p = synth_profile(FRAME.chips(9), 200, 5.0, 0.0)
    dec = decode_profile(p, FRAME)
    assert dec.id == 9
    assert dec.hamming == 0
    assert dec.rows_per_chip == pytest.approx(5.0, rel=1e-3)
    assert abs(dec.bleed_rows) < 0.3  # the threshold above half trims bright runs a little
    assert dec.run_margin > 0.9


def test_bleeding_is_measured():
    for widen in (1.0, 2.0, 3.0):
        p = synth_profile(FRAME.chips(6), 220, 6.0, 3.3, bleed_rows=widen)
        dec = decode_profile(p, FRAME)
        assert dec.id == 6
        # bright runs ``widen`` rows longer than their chips, dark ones as much shorter
        assert dec.bleed_rows == pytest.approx(widen, abs=0.35)


def test_known_chip_length_is_used():
    p = synth_profile(FRAME.chips(3), 180, 4.4, 1.7, bleed_rows=1.0)
    dec = decode_profile(p, FRAME, rows_per_chip=4.4)
    assert dec.id == 3
    assert dec.rows_per_chip == 4.4


def test_steady_light_gives_no_id_with_a_reason():
    rng = np.random.default_rng(2)
    steady = 200.0 + 2.0 * rng.standard_normal(150)
    dec = decode_profile(steady, FRAME)
    assert dec.id is None and not dec
    assert "stripes" in dec.reason


def test_less_than_one_frame_gives_no_id_with_a_reason():
    rng = np.random.default_rng(3)
    for fid in range(16):
        rpc = rng.uniform(3.0, 8.0)
        p = synth_profile(
            FRAME.chips(fid), int(0.8 * FRAME.n_chips * rpc), rpc, rng.uniform(0, FRAME.n_chips)
        )
        dec = decode_profile(p, FRAME)
        assert dec.id is None, (fid, dec)
        assert dec.reason
        assert dec.frames < 1.0


def test_tiny_profile_gives_no_id():
    dec = decode_profile(np.array([10.0, 200, 10, 200, 10]), FRAME)
    assert dec.id is None
    assert "rows" in dec.reason


@pytest.mark.parametrize("a", range(16))
def test_copies_that_disagree_are_refused(a):
    """A profile whose first frame is ID a and second frame ID b gives no ID."""
    rng = np.random.default_rng(50 + a)
    for b in range(16):
        if b == a:
            continue
        rpc = rng.uniform(3.0, 8.0)
        chips = np.concatenate([FRAME.chips(a), FRAME.chips(b)])
        p = synth_profile(
            chips,
            int(2 * FRAME.n_chips * rpc) - 1,
            rpc,
            0.0,
            repeat=False,
            bleed_rows=rng.uniform(0, 0.3 * rpc),
            noise=2.0,
            rng=rng,
        )
        dec = decode_profile(p, FRAME)
        assert dec.id is None, (a, b, dec)
        assert dec.reason


def test_other_frame_formats_decode():
    frame = FrameFormat("1111", 5, "000")
    rng = np.random.default_rng(4)
    for fid in rng.choice(frame.n_ids, 8, replace=False):
        case = random_case(rng)
        case["n_rows"] = int(1.5 * frame.n_chips * case["rows_per_chip"])
        dec = decode_profile(synth_profile(frame.chips(int(fid)), rng=rng, **case), frame)
        assert dec.id == fid


def test_find_runs_locates_edges_between_rows():
    # a bright run from 10.25 to 20.75 rows (exact area sampling), threshold half-way
    p = synth_profile(np.array([0, 1, 0]), 32, 10.5, 1.0 - 10.25 / 10.5, repeat=False)
    runs = find_runs(p, 120.0)
    assert runs.edges.size == 2
    assert runs.rising.tolist() == [True, False]
    assert runs.bright.tolist() == [False, True, False]
    # edge positions in row-centre coordinates (row k covers [k - 0.5, k + 0.5]), to a
    # fraction of a row (linear interpolation between row centres)
    assert runs.edges == pytest.approx([10.25 - 0.5, 20.75 - 0.5], abs=0.2)
    assert runs.lengths.sum() == pytest.approx(p.size)


def test_row_profile_rows_and_columns():
    rng = np.random.default_rng(5)
    values = rng.uniform(0, 255, 40)
    yy, xx = np.mgrid[:40, :40]
    disc = (yy - 19.5) ** 2 + (xx - 19.5) ** 2 <= 18.0**2
    striped = np.where(disc, values[:, None], 0.0)
    prof, first = row_profile(striped, disc, "rows")
    assert first > 0 and prof.size < 40
    assert prof == pytest.approx(values[first : first + prof.size])
    prof_t, first_t = row_profile(striped.T, disc.T, "columns")
    assert first_t == first
    assert prof_t == pytest.approx(prof)


def _lamp(shape_of_rho, stripes: np.ndarray, radius: float = 30.0, clip: float = 255.0):
    """A lamp (72 x 72) whose radial shape times each row's on-fraction, clipped, in uint8;
    with its mask (the lit area down to 2 % of its level) and its outline ellipse."""
    yy, xx = np.mgrid[0:72, 0:72].astype(float)
    rho = np.hypot(xx - 35.5, yy - 36.2) / radius
    shape = shape_of_rho(rho)
    img = np.clip(shape * stripes[:, None], 0, clip)
    mask = shape > 0.02 * shape.max()
    return np.round(img).astype(np.uint8), mask, np.array([35.5, 36.2]), np.full(2, 2 * radius)


@pytest.mark.parametrize("axis", ["rows", "columns"])
def test_shape_profile_follows_the_led_not_the_lamps_glow(axis):
    rng = np.random.default_rng(5)
    on = np.repeat(rng.integers(0, 2, 12), 6)[:72] * 0.9 + 0.1  # 6 rows per chip, off at 10 %

    def glowing(rho):  # a hot core, a disc, and a glow decaying beyond it
        disc = np.clip(1.0 + 1.0 * np.exp(-((rho / 0.4) ** 2)), 0, None) * (rho <= 1)
        return 120.0 * np.where(rho <= 1, disc, 0.35 * np.exp(-(rho - 1) / 0.5))

    img, mask, centre, axes = _lamp(glowing, on)
    if axis == "columns":
        img, mask, centre = img.T, mask.T, centre[::-1]
    shaped, first = shape_profile(img, mask, axis, centre, axes, 0.0)
    plain, first2 = row_profile(img, mask, axis)
    assert first == first2 and shaped.size == plain.size
    truth = on[first : first + shaped.size]
    # the shaped profile is the on-fraction times one level; the row mean is not
    for prof, ok in ((shaped, True), (plain, False)):
        scale = float(prof @ truth / (truth @ truth))
        err = np.sqrt(np.mean((prof / scale - truth) ** 2))  # RMS, in on-fractions
        assert (err < 0.03) == ok, (err, ok)


def test_shape_profile_of_a_plain_disc_is_its_row_mean():
    rng = np.random.default_rng(6)
    on = np.repeat(rng.integers(0, 2, 12), 6)[:72] * 0.95 + 0.05
    img, mask, centre, axes = _lamp(lambda rho: 240.0 * (rho <= 1), on)
    img = np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
    shaped, _ = shape_profile(img, mask, "rows", centre, axes, 0.0)
    plain, _ = row_profile(img, mask, "rows")
    assert np.abs(shaped - plain).max() < 0.03 * plain.max()


def test_mask_pixels_found_as_numpy_finds_them():
    # the flat test's pixels by OpenCV: NumPy's rows and columns, in its order, of any mask
    # (every k-th row and column of one too), and none of an empty one
    rng = np.random.default_rng(8)
    for h, w, step in ((37, 61, 1), (64, 23, 3), (5, 90, 2)):
        mask = (rng.uniform(size=(h, w)) < 0.3).astype(np.uint8)[::step, ::step]
        ys, xs = _nonzero(mask)
        np.testing.assert_array_equal(ys, np.nonzero(mask)[0])
        np.testing.assert_array_equal(xs, np.nonzero(mask)[1])
    ys, xs = _nonzero(np.zeros((9, 7), np.uint8))
    assert ys.size == xs.size == 0


def test_profiles_decoded_together_as_one_by_one():
    # every refusal and every ID, profiles of all lengths (a steady light, too small, too few
    # stripes, noisy ones): the batch gives each profile's own decode, field for field
    rng = np.random.default_rng(21)
    profiles = [np.full(20, 90.0), np.array([1.0, 2.0, 3.0]), np.array([10.0, 200] * 3)]
    for _ in range(60):
        case = random_case(rng)
        case["n_rows"] = int(rng.integers(8, 300))
        case["noise"] = rng.uniform(0.0, 30.0)
        profiles.append(synth_profile(FRAME.chips(int(rng.integers(16))), rng=rng, **case))
    for rpc in (None, 4.2):
        together = decode_profiles(profiles, FRAME, rows_per_chip=rpc)
        alone = [decode_profiles([p], FRAME, rows_per_chip=rpc)[0] for p in profiles]
        assert [repr(d) for d in together] == [repr(d) for d in alone]
    reasons = {d.reason.split(" (")[0] for d in together}
    assert {"", "too small to decode", "no stripes"} <= reasons


def _direct_chip_length(d: np.ndarray) -> float:
    """A profile's chip length from its spacings ``d`` as a plain grid search finds it: every
    chip length of the grid tried, each spacing's squared residual summed, then refined."""
    shortest = d.min()
    grid = np.arange(max(0.8, shortest / 4.6), min(64.0, shortest / 1.6), 0.01)
    x = d[None, :] / grid[:, None]
    x -= np.minimum(np.rint(x), 4)
    t = grid[int(np.argmin(np.square(x * grid[:, None]).sum(axis=1)))]
    m = np.clip(np.rint(d / t), 2, 4)
    return float((d * m).sum() / (m * m).sum())


def _direct_bleed(lengths: np.ndarray, bright: np.ndarray, t: float) -> float:
    """A profile's bleeding from its interior runs as a plain grid search finds it."""
    grid = np.linspace(-0.95 * t, 0.95 * t, 191)
    x = (np.where(bright, lengths, -lengths)[None, :] - grid[:, None]) / np.where(bright, t, -t)
    x -= np.clip(np.rint(x), 1, 2)
    return float(grid[int(np.argmin(np.square(x).sum(axis=1)))])


def test_grid_searches_pick_what_a_direct_search_picks():
    # the chip length's and the bleeding's grids are costed by running sums: the same grid
    # values as costing every one term by term, ties (periodic stripes whose runs fit two
    # bleedings equally) included
    rng = np.random.default_rng(8)
    profiles = []
    # stripes of equal runs: the bleeding b and b + t fit alike (the grid's steps are a
    # hundredth of a chip), their costs equal up to rounding
    periodic = [("11100", 90, 3.25), ("1110", 90, 4.0), ("110", 90, 4.25), ("1100", 150, 5.0)]
    for pattern, n_rows, rpc in periodic:
        chips = np.array([int(c) for c in pattern * 60], dtype=np.uint8)
        profiles.append(synth_profile(chips, n_rows, rpc))
    for _ in range(40):
        case = random_case(rng)
        case["noise"] = rng.uniform(0.0, 20.0)
        profiles.append(synth_profile(FRAME.chips(int(rng.integers(16))), rng=rng, **case))
    lo, hi = stripe_levels_many(profiles)
    r = flat_runs(profiles, lo + 0.6 * (hi - lo))
    t = chip_lengths(r, 64.0)
    d, p = chips_mod._spacings(r)
    told = 0
    for k in range(len(profiles)):
        if np.count_nonzero(p == k) >= 2 and np.isfinite(t[k]):
            assert t[k] == _direct_chip_length(d[p == k])
            told += 1
    which = np.flatnonzero((r.n_edges >= 4) & np.isfinite(t))
    b = bleeds(r, t, which)
    ties = 0
    for k, bleed in zip(which.tolist(), b.tolist(), strict=True):
        runs = slice(r.run_starts[k] + 1, r.run_starts[k] + r.n_edges[k])  # the interior ones
        assert bleed == _direct_bleed(r.lengths[runs], r.bright[runs], t[k])
        ties += k < len(periodic)
    assert told >= 40 and which.size >= 40 and ties == len(periodic)


def test_shape_profile_of_a_disc_clipping_in_its_glow_reads_one_response():
    # a disc 4 times full scale in an unclipped glow: the rows through the disc clip in the
    # bright chips (shallow dips), those beyond it along the readout cross only the glow
    # (deep dips); the profile is read through the disc's response alone, so rows of the
    # same on-fraction agree, and it is the disc's knee that fits it
    rng = np.random.default_rng(11)
    chips = rng.choice([0.05, 0.2, 0.45, 1.0], 20)
    on = np.repeat(chips, 6)[:110]  # 6 rows per chip
    yy, xx = np.mgrid[0:110, 0:110].astype(float)
    rho = np.hypot(xx - 54.6, yy - 55.3) / 30.0
    shape = np.where(rho <= 1, 1020.0, 150.0 * np.exp(-(rho - 1) / 0.5))
    img = np.round(np.clip(shape * on[:, None] + rng.normal(0, 1.5, shape.shape), 0, 255))
    mask = shape > 60.0  # lit in the bright chips: the disc and the glow around it
    centre = np.array([54.6, 55.3])
    prof, first = shape_profile(img.astype(np.uint8), mask, "rows", centre, np.full(2, 60.0), 0.0)
    truth = on[first : first + prof.size]
    assert prof.size >= 58  # the disc's rows at least
    knee = 0.25  # the disc's: full scale at a quarter of its on-level
    model = np.minimum(truth, knee) / knee
    a = np.vstack([model, np.ones_like(model)]).T
    resid = prof - a @ np.linalg.lstsq(a, prof, rcond=None)[0]
    assert np.sqrt(np.mean(resid**2)) < 0.03 * np.ptp(prof)


def test_shape_profile_of_a_lamp_clipping_at_its_core_only_keeps_every_row():
    # a hot core clips, the rest of the disc does not: the profile keeps the disc's rows
    rng = np.random.default_rng(12)
    on = np.repeat(rng.choice([0.05, 0.2, 0.45, 1.0], 20), 6)[:110]
    yy, xx = np.mgrid[0:110, 0:110].astype(float)
    rho = np.hypot(xx - 54.6, yy - 55.3) / 30.0
    shape = np.where(rho <= 1, 150.0 * (1 + 2.5 * np.exp(-((rho / 0.4) ** 2))), 0.0)
    img = np.round(np.clip(shape * on[:, None] + rng.normal(0, 1.5, shape.shape), 0, 255))
    mask = shape > 60.0
    centre = np.array([54.6, 55.3])
    prof, _ = shape_profile(img.astype(np.uint8), mask, "rows", centre, np.full(2, 60.0), 0.0)
    assert prof.size >= 50  # the core alone clips on some 29 rows


def test_shape_profile_of_a_lamp_below_full_scale_keeps_its_glow_rows():
    # a disc just under the sensor's full scale in a glow: nothing clips, one response
    # throughout, and the rows beyond the disc stay in the profile
    rng = np.random.default_rng(13)
    on = np.repeat(rng.choice([0.05, 0.2, 0.45, 1.0], 20), 6)[:110]
    yy, xx = np.mgrid[0:110, 0:110].astype(float)
    rho = np.hypot(xx - 54.6, yy - 55.3) / 30.0
    shape = np.where(rho <= 1, 240.0, 150.0 * np.exp(-(rho - 1) / 0.5))
    img = np.round(np.clip(shape * on[:, None] + rng.normal(0, 1.5, shape.shape), 0, 255))
    mask = shape > 60.0
    centre = np.array([54.6, 55.3])
    prof, _ = shape_profile(img.astype(np.uint8), mask, "rows", centre, np.full(2, 60.0), 0.0)
    assert prof.size >= 75  # the disc's 60 rows and its glow's beyond


def test_shape_profile_drops_end_lines_that_cross_only_a_faint_rim():
    # a lamp in a glow that fades to nothing, its outline reaching lines where the glow is a
    # count or two; there a neighbour's stray light (8 counts over a few pixels) divided by
    # the faint on-level would read many times brighter than the LED ever is: those lines
    # are too noisy to keep, and the rest of the profile is the on-fraction
    rng = np.random.default_rng(14)
    on = np.repeat(rng.choice([0.05, 0.3, 1.0], 20), 6)[:110]
    yy, xx = np.mgrid[0:110, 0:110].astype(float)
    rho = np.hypot(xx - 54.6, yy - 55.3) / 30.0
    shape = np.where(rho <= 1, 200.0, 60.0 * np.exp(-(rho - 1) / 0.25))
    img = shape * on[:, None] + 8.0 * ((yy < 6) & (np.abs(xx - 54.6) < 4))  # stray light
    img = np.round(np.clip(img + rng.normal(0, 0.3, shape.shape), 0, 255)).astype(np.uint8)
    mask = shape > 0.4
    centre = np.array([54.6, 55.3])
    prof, first = shape_profile(img, mask, "rows", centre, np.full(2, 60.0), 0.0)
    truth = on[first : first + prof.size]
    assert prof.size >= 60  # the disc's rows at least
    scale = float(prof @ truth / (truth @ truth))
    assert np.max(prof) < 1.3 * scale  # no line brighter than the LED fully on
    assert np.sqrt(np.mean((prof / scale - truth) ** 2)) < 0.05


def test_shape_profile_of_a_lamp_whose_hot_core_clips_over_most_of_its_lines_keeps_them():
    # a lamp at 0.72 full scale whose hot core (3.2 times its rim) clips out to some 0.55 of
    # its radius: most pixels of the core's lines clip, but barely (the core's dark chips
    # read about as many times the on-fraction as the face around it), so the lamp is read as
    # one, all its lines kept (its core's lines alone were 34 to 36 of its 56)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        on = np.repeat(rng.choice([0.05, 0.2, 0.45, 1.0], 20), 6)[:110]
        yy, xx = np.mgrid[0:110, 0:110].astype(float)
        rho = np.hypot(xx - 54.6, yy - 55.3) / 30.0
        shape = np.where(rho <= 1, 184.0 * (1 + 2.2 * np.exp(-((rho / 0.4) ** 2))), 0.0)
        img = np.round(np.clip(shape * on[:, None] + rng.normal(0, 1.5, shape.shape), 0, 255))
        centre = np.array([54.6, 55.3])
        prof, _ = shape_profile(
            img.astype(np.uint8), shape > 60.0, "rows", centre, np.full(2, 60.0), 0.0
        )
        assert prof.size >= 54
