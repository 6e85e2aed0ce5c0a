"""Tests for camvlp.analysis.study.montecarlo: the thesis' chapter 4 findings.

Bounds come from the thesis text (figures 3.8, 3.10, 4.2 to 4.5) or from first-order
reasoning, not from this code's output.
"""

from __future__ import annotations

from study_helpers import cam, room  # noqa: F401  (fixtures)

from camvlp.analysis.study import (
    monte_carlo_study,
)

# ------------------------------------------------------------------------- Monte Carlo


def test_monte_carlo_error_scales_with_noise(cam, room):
    # small noise propagates linearly: twice the pixel noise, twice the position error
    kw = dict(positions_m=(0.3, 0, -0.2), euler_deg=(85, 5, 0), trials=400, seed=3, rounding=False)
    a = monte_carlo_study(cam, room, noise_px=0.5, **kw).summary()
    b = monte_carlo_study(cam, room, noise_px=1.0, **kw).summary()
    assert a["failures"] == b["failures"] == 0
    assert 1.7 < b["mean_error_m"] / a["mean_error_m"] < 2.3
    assert a["median_error_m"] <= a["p95_error_m"] <= a["max_error_m"]
    s = monte_carlo_study(cam, room, survey_error_m=0.01, **kw).summary()
    assert 0.001 < s["mean_error_m"] < 0.2  # 1 cm map errors: centimetres, not metres


def test_monte_carlo_per_pose_summary(cam, room):
    res = monte_carlo_study(
        cam,
        room,
        positions_m=[(0, 0, 0), (0.5, 0, 0)],
        euler_deg=(90, 0, 0),
        noise_px=0.5,
        trials=10,
    )
    s = res.summary()
    assert res.errors_m.shape == (2, 10)
    assert [p["position_m"] for p in s["per_pose"]] == [[0, 0, 0], [0.5, 0, 0]]
