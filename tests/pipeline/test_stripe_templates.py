"""The model decoder's templates: fitted several at once as each alone, and kept by the
parameters they are made of (seeded)."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp import FrameFormat
from camvlp.pipeline.decode.stripe_model import (
    KeptArrays,
    SensorModel,
    direct_fit,
    knee_templates,
    model_spectra,
    templates_batch,
)

CHIPS = FrameFormat().codebook


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_templates_fitted_together_fit_as_each_alone_to_the_last_bit(seed):
    rng = np.random.default_rng(seed)
    n, period = int(rng.integers(40, 300)), int(rng.integers(100, 600))
    p, w = rng.normal(size=n), rng.uniform(0.5, 1.0, size=n)
    tfs = rng.uniform(size=(5, period))
    x = (np.arange(n) * rng.uniform(1.0, 20.0)) % period
    phases = rng.uniform(0.0, period, size=9)
    together = np.stack(direct_fit(p, w, tfs, x, phases))  # (3, templates, phases)
    alone = np.stack([np.stack(direct_fit(p, w, t, x, phases)) for t in tfs], axis=1)
    assert together.shape == (3, 5, 9)
    assert np.array_equal(together, alone)


def test_kept_templates_are_those_made_afresh_read_only_and_keyed_by_their_parameters():
    model = SensorModel(3.1, exposure_chips=0.4, knee=0.7, gamma=1.0, blur_rows=0.6)
    knees = np.array([0.3, 0.5, 1.0])
    kept = knee_templates(CHIPS, model, knees, 16)
    fresh = templates_batch(CHIPS, 3.1, np.full(3, 0.4), knees, np.ones(3), np.full(3, 0.6), 16)
    assert np.array_equal(kept, fresh)
    assert knee_templates(CHIPS, model, knees.copy(), 16) is kept  # kept, not made again
    with pytest.raises(ValueError):
        kept[0, 0, 0] = 2.0  # read-only: a caller cannot spoil another's
    spectra = model_spectra(CHIPS, model, 16)
    assert model_spectra(CHIPS.copy(), model, 16) is spectra
    other = model_spectra(CHIPS, SensorModel(3.1, exposure_chips=0.5, knee=0.7, blur_rows=0.6), 16)
    assert other is not spectra and not np.array_equal(other[0], spectra[0])
    assert model_spectra(CHIPS[:4], model, 16)[0].shape[0] == 4  # the chips are in the key


def test_kept_arrays_drop_the_least_recently_used_beyond_their_budget():
    kept = KeptArrays(budget=3 * 800)  # three arrays of 100 float64
    made = []

    def make(k):
        made.append(k)
        return (np.full(100, float(k)),)

    for k in (1, 2, 3):
        kept.get((k,), lambda k=k: make(k))
    kept.get((1,), lambda: make(1))  # 1 used again: 2 is now the least recent
    kept.get((4,), lambda: make(4))  # over the budget: 2 dropped
    assert made == [1, 2, 3, 4]
    kept.get((1,), lambda: make(1))
    kept.get((2,), lambda: make(2))  # made again
    assert made == [1, 2, 3, 4, 2]
    big = kept.get(("big",), lambda: (np.zeros(1000),))  # over the whole budget: not kept
    assert big[0].size == 1000 and kept.get(("big",), lambda: (np.ones(1),))[0].size == 1
