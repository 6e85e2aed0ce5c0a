"""The run-length fast path before the model fit (camvlp.pipeline.decode.manchester)."""

from __future__ import annotations

import numpy as np
from tests.pipeline.test_model_decode import FRAME, synth

from camvlp import Camera, Fixture, FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.manchester import decode_manchester

CAMERA = Camera.from_focal(1920, 1080, 1400.0)  # no row time: the chip length is measured
RPC = 5.0


def fmap(ids) -> FixtureMap:
    return FixtureMap(tuple(Fixture(int(i), np.array([i, 0.0, 2.0])) for i in ids))


def profiles(ids, rng, *, reverse: bool = False):
    out = []
    for i in ids:
        n = int(rng.uniform(1.4, 2.2) * FRAME.n_chips * RPC)
        p = synth(FRAME.chips(int(i)), n, RPC, rng.uniform(0, 18), 0.4, noise=2.0, rng=rng)
        out.append(p[::-1] if reverse else p)
    return out


def test_reversed_ids_of_the_default_format():
    rev = FRAME.reversed_ids
    for a, b in ((0, 14), (2, 6), (4, 10), (8, 12)):
        assert rev[a] == b and rev[b] == a
    assert all(rev[i] < 0 for i in (1, 3, 5, 7, 9, 11, 13, 15))


def test_clean_stripes_need_no_model_fit():
    rng = np.random.default_rng(1)
    ids = [1, 3, 5, 6, 9]
    man = decode_manchester(profiles(ids, rng), Readout.ROWS, True, CAMERA, fmap(ids))
    assert [d.id for d in man.decodes] == ids
    assert all(d.method == "runs" and d.hamming == 0 for d in man.decodes)
    assert man.model is None and np.isnan(man.exposure_chips)
    assert abs(man.rows_per_chip / RPC - 1) < 0.02


def test_only_the_refused_fixture_goes_to_the_model():
    rng = np.random.default_rng(2)
    ids = [1, 3, 5, 6, 9]
    ps = profiles(ids, rng)
    ps[2] = ps[2][: int(0.9 * FRAME.n_chips * RPC)]  # under one frame: the fast path refuses
    man = decode_manchester(ps, Readout.ROWS, True, CAMERA, fmap(ids))
    assert man.decodes[2].method == "model"
    assert all(man.decodes[k].method == "runs" for k in (0, 1, 3, 4))
    assert man.model is not None
    assert man.decodes[2].id in (None, 5)  # never another ID


def test_a_fixture_too_short_to_read_costs_no_model_fit(monkeypatch):
    import camvlp.pipeline.decode.manchester as manchester

    fits = []
    fit = manchester.estimate_photo_model
    monkeypatch.setattr(
        manchester, "estimate_photo_model", lambda *a, **k: fits.append(1) or fit(*a, **k)
    )
    rng = np.random.default_rng(2)
    ids = [1, 3, 5, 6, 9]
    ps = profiles(ids, rng)
    ps[2] = ps[2][: int(0.7 * FRAME.n_chips * RPC)]  # under the 0.8 frame any decode needs
    man = decode_manchester(ps, Readout.ROWS, True, CAMERA, fmap(ids))
    assert not fits and man.model is None
    assert man.decodes[2].id is None and man.decodes[2].reason.startswith("spans 0.7")
    assert [man.decodes[k].id for k in (0, 1, 3, 4)] == [1, 3, 6, 9]
    # 0.85 frame: long enough to try, the fit runs
    ps[2] = profiles([5], np.random.default_rng(9))[0][: int(0.85 * FRAME.n_chips * RPC)]
    decode_manchester(ps, Readout.ROWS, True, CAMERA, fmap(ids))
    assert fits


def test_direction_from_the_fast_path_when_fixtures_say_it():
    rng = np.random.default_rng(3)
    ids = [1, 3, 5, 2, 6]
    ps = profiles(ids, rng, reverse=True)  # the sensor read them the other way
    man = decode_manchester(ps, Readout.ROWS, False, CAMERA, fmap(ids))
    assert man.readout == Readout.ROWS_REVERSED
    assert [d.id for d in man.decodes] == ids


def test_reversal_pairs_only_are_left_to_the_model_and_the_pose():
    rng = np.random.default_rng(4)
    ids = [0, 14, 2, 6]
    ps = profiles(ids, rng)
    man = decode_manchester(ps, Readout.ROWS, False, CAMERA, fmap(ids))
    # read either way the IDs are the map's: the pose must decide, and each direction is
    # read as if it were known (its run-length IDs, the model for the rest)
    assert man.other is not None
    rev = FRAME.reversed_ids
    assert [d.id for d in man.decodes] == ids
    assert [d.id for d in man.other] == [int(rev[i]) for i in ids]
    known = decode_manchester(ps, Readout.ROWS, True, CAMERA, fmap(ids))
    assert [type(d) for d in man.decodes] == [type(d) for d in known.decodes]


def test_row_weights_let_the_model_read_through_noisy_end_rows():
    # a disc's rows hold fewer pixels toward its ends, so their means are noisier; weighed
    # by their pixels the model fits what the rows can tell, and names more IDs, never a
    # wrong one (saturated LEDs exposed for a whole chip: the run-length path refuses most)
    ids = [1, 3, 5, 7, 9, 11, 13]
    room = FixtureMap(tuple(Fixture(i, np.array([i, 0.0, 2.0])) for i in range(16)))
    decoded = {False: 0, True: 0}
    for seed in range(6):
        rng = np.random.default_rng(seed)
        ps, ws = [], []
        for i in ids:
            n = int(rng.uniform(1.3, 1.8) * FRAME.n_chips * RPC)
            p = synth(
                FRAME.chips(i), n, RPC, rng.uniform(0, 18), 1.0, brightness=6.0, off=0.03, blur=0.8
            )
            y = (np.arange(n) + 0.5) / n * 2 - 1
            pixels = np.maximum(np.round(60 * np.sqrt(1 - y * y)), 1)  # a disc's chords
            ps.append(p + rng.normal(size=n) * 150.0 / np.sqrt(pixels))
            ws.append(pixels)
        for weighed in (False, True):
            man = decode_manchester(ps, Readout.ROWS, True, CAMERA, room, ws if weighed else None)
            got = [d.id for d in man.decodes]
            assert all(g in (None, i) for g, i in zip(got, ids, strict=True))  # never wrong
            decoded[weighed] += sum(g == i for g, i in zip(got, ids, strict=True))
    assert decoded[True] >= decoded[False] + 3, decoded
