"""The fits of glowing lights run their matrix products on one BLAS thread."""

from __future__ import annotations

import numpy as np
import pytest
from tests.pipeline.test_glow import _photo
from threadpoolctl import threadpool_info, threadpool_limits

import camvlp.pipeline.lamp.light_wave as light_wave
import camvlp.pipeline.lamp.radial as radial
from camvlp.imaging.threads import one_blas_thread
from camvlp.pipeline.detect.candidates import detect_fixtures
from camvlp.pipeline.lamp.glow import centred_on_glow


def _blas_threads() -> set[int]:
    """The threads of NumPy's BLAS (the matrix products'; SciPy may bring its own)."""
    return {
        i["num_threads"]
        for i in threadpool_info()
        if i["user_api"] == "blas" and "numpy" in i["filepath"]
    }


@pytest.fixture
def two_threads():
    """BLAS at two threads around the test (whatever the machine's cores), as before it
    after."""
    if not _blas_threads():
        pytest.skip("threadpoolctl finds no BLAS of NumPy's here")
    with threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() == {2}
        yield


def test_a_glowing_lights_fit_runs_on_one_blas_thread(monkeypatch, two_threads):
    seen = []
    real = light_wave.shape_fit

    def spy(*args, **kwargs):
        if len(seen) < 3:  # (threadpool_info costs a millisecond)
            seen.append(_blas_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(radial, "shape_fit", spy)
    monkeypatch.setattr(light_wave, "shape_fit", spy)
    photo, _ = _photo(0, halo=0.4, brightness=1.0)
    blobs = [b for b in detect_fixtures(photo.image).blobs if not b.touches_border]
    moved = centred_on_glow(photo.image, blobs, "rows")
    assert any(np.any(m.pixel != b.pixel) for m, b in zip(moved, blobs, strict=True))
    assert seen and all(s == {1} for s in seen)
    assert _blas_threads() == {2}  # the limit before, restored


def test_the_limit_is_restored_when_the_fit_raises(two_threads):
    @one_blas_thread
    def fails():
        assert _blas_threads() == {1}
        raise ValueError("bad fit")

    with pytest.raises(ValueError, match="bad fit"):
        fails()
    assert _blas_threads() == {2}
