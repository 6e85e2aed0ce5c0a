"""A disc that shows less than a frame: its pieces of code, and the ID they say once gathered
over several frames (:mod:`camvlp.pipeline.decode.partial`), never a wrong one."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.model.linecode import FrameFormat, manchester_encode
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.partial import ChipEvidence, PartialRead, piece_fits, read_partials

LONG = FrameFormat("1111", 10, "000", 8)  # 50 chips, IDs at least 4 chips apart
RPC = 3.1  # rows a chip


def profile(stream: np.ndarray, start: float, chips: float, rng, rpc: float = RPC):
    """The row profile of a disc that shows ``chips`` chips of the repeating ``stream`` from
    chip ``start`` on (each row the mean of its exposure, sensor noise added)."""
    rows = int(chips * rpc)
    t = start + (np.arange(rows)[:, None] + np.linspace(0.0, 1.0, 9)[None, :]) / rpc
    on = stream[np.floor(t).astype(int) % stream.size].mean(axis=1)
    return 30.0 + 190.0 * on + rng.normal(0.0, 3.0, rows)


def gathered(stream, frames, rng, *, chips=30.0, flips=0.0, readout=Readout.ROWS, told=True):
    """Each frame's decision on one light sending ``stream``, its disc showing ``chips``
    chips at a random phase a frame (the chips read flipped at the rate ``flips``), read
    with ``readout``, its direction ``told`` or not."""
    evidence = ChipEvidence(LONG, 12)
    out = []
    for k in range(frames):
        p = profile(stream, rng.uniform(0, stream.size), chips, rng)
        (read,) = read_partials([p], LONG, readout, rows_per_chip=RPC)
        if read is not None and flips:
            pieces = [np.where(rng.random(c.size) < flips, 1 - c, c) for c in read.pieces]
            read = PartialRead(tuple(pieces), piece_fits(LONG, pieces))
        if read is not None:
            evidence.add(k, read)
        out.append(evidence.decide(k, readout.reversed if told else None))
    return out


def test_a_disc_under_a_frame_is_read_in_pieces_that_fit_its_id():
    rng = np.random.default_rng(1)
    stream = LONG.chips(402)
    (read,) = read_partials([profile(stream, 7.3, 31.0, rng)], LONG, Readout.ROWS)
    assert read is not None and sum(p.size for p in read.pieces) >= 25
    assert read.fits.shape == (len(read.pieces), 2, LONG.n_ids)
    assert (read.fits[:, 0, 402] == 0).all()  # each piece is somewhere in its frame
    assert read.rows_per_chip == pytest.approx(RPC, rel=0.03)  # (measured)
    # a disc that shows a whole frame is the single-photo decoders'
    whole = profile(stream, 7.3, 1.3 * LONG.n_chips, rng)
    assert read_partials([whole], LONG, Readout.ROWS, rows_per_chip=RPC) == [None]


@pytest.mark.parametrize("seed", range(4))
def test_pieces_of_a_few_frames_give_the_id(seed):
    rng = np.random.default_rng(seed)
    fid = int(rng.integers(LONG.n_ids))
    said = gathered(LONG.chips(fid), 10, rng)
    first = next(k for k, g in enumerate(said) if g)
    assert first < 10 and all(g.id == fid for g in said[first:])
    assert said[first].covered == LONG.n_chips and said[first].distance == 0
    # before: too few chips, or IDs that fit nearly alike
    assert not said[0] and "chips of a frame gathered" in said[0].reason


def test_the_direction_is_weighed_when_not_known():
    rng = np.random.default_rng(5)
    said = gathered(LONG.chips(615), 10, rng, readout=Readout.ROWS_REVERSED, told=False)
    assert said[-1].id == 615 and said[-1].reversed
    # (told: read backward) the same chips along the axis read as the sensor read them
    evidence = ChipEvidence(LONG, 12)
    for k in range(10):
        p = profile(LONG.chips(615), rng.uniform(0, 50), 30.0, rng)
        (read,) = read_partials([p], LONG, Readout.ROWS_REVERSED, rows_per_chip=RPC)
        evidence.add(k, read)
    assert evidence.decide(9, True).id == 615
    assert evidence.decide(9, None).id == 615
    assert evidence.decide(9, False).id is None  # read forward, no ID's frame


def test_an_id_whose_frame_read_backwards_is_another_s_needs_the_direction():
    thesis = FrameFormat()  # IDs 0 and 14 are each other's frames read backwards
    assert thesis.reversed_ids[0] == 14
    rng = np.random.default_rng(2)
    evidence = ChipEvidence(thesis, 12)
    for k in range(8):
        p = profile(thesis.chips(0), rng.uniform(0, 18), 12.0, rng)
        (read,) = read_partials([p], thesis, Readout.ROWS, rows_per_chip=RPC)
        if read is not None:
            evidence.add(k, read)
    unknown = evidence.decide(7, None)
    assert unknown.id is None and "alike" in unknown.reason
    assert evidence.decide(7, False).id == 0
    # an ID whose frame read backwards is its own is that ID either way: given, the
    # direction untold
    own = FrameFormat("111", 5, "00")
    assert own.reversed_ids[6] == 6
    evidence = ChipEvidence(own, 12)
    for k in range(8):
        p = profile(own.chips(6), rng.uniform(0, own.n_chips), 13.0, rng)
        (read,) = read_partials([p], own, Readout.ROWS, rows_per_chip=RPC)
        if read is not None:
            evidence.add(k, read)
    said = evidence.decide(7, None)
    assert said.id == 6 and said.reversed is None
    assert evidence.decide(7, True).id == 6 and evidence.decide(7, True).reversed


@pytest.mark.parametrize("seed", range(6))
def test_a_corrupted_stream_gives_no_wrong_id(seed):
    rng = np.random.default_rng(seed)
    fid = int(rng.integers(LONG.n_ids))
    # the light's stream as sent: its ID within ten frames
    assert gathered(LONG.chips(fid), 10, rng)[-1].id == fid
    # random data (a light sending data): no ID
    data = manchester_encode(rng.integers(0, 2, 256))
    assert not any(gathered(data, 12, rng))
    # its frame with one or two bits flipped (no ID's frame; two chips or more from each):
    # no ID
    for n in (1, 2):
        bits = np.array(list(LONG.bits(fid)), dtype=int)
        at = rng.choice(np.arange(4, 4 + 18), n, replace=False)  # in the ID or its check
        bits[at] ^= 1
        assert not any(gathered(manchester_encode(bits), 12, rng))
    # its chips read wrong now and then (1 % of them): its ID or none, never another
    assert all(g.id in (None, fid) for g in gathered(LONG.chips(fid), 12, rng, flips=0.01))


def test_the_pieces_of_two_lights_give_no_id():
    # a light taken for another (the two followed as one): conflicting chips, no ID
    rng = np.random.default_rng(3)
    evidence = ChipEvidence(LONG, 12)
    for k in range(12):
        fid = (37, 901)[k % 2]
        p = profile(LONG.chips(fid), rng.uniform(0, 50), 30.0, rng)
        (read,) = read_partials([p], LONG, Readout.ROWS, rows_per_chip=RPC)
        evidence.add(k, read)
        got = evidence.decide(k)
        assert got.id is None
    assert "fit no ID" in got.reason
    # the old pieces leave the window: once only one light's are left, its ID
    for k in range(12, 24):
        p = profile(LONG.chips(37), rng.uniform(0, 50), 30.0, rng)
        (read,) = read_partials([p], LONG, Readout.ROWS, rows_per_chip=RPC)
        evidence.add(k, read)
    assert evidence.decide(23, False).id == 37
