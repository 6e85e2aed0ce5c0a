"""The coverage study with gravity: where two or three fixtures give a fix, and its error."""

from __future__ import annotations

import numpy as np
import pytest
from study_helpers import cam, room  # noqa: F401  (fixtures)

from camvlp.analysis.study import coverage_study
from camvlp.model.fixtures import Fixture, FixtureMap

KW = dict(step_m=0.5, tilt_max_deg=15, tilt_step_deg=7.5, seed=2)


@pytest.fixture(scope="module")
def studies(cam, room):
    return {k: coverage_study(cam, room, gravity=True, min_fixtures=k, **KW) for k in (2, 3, 4)}


def test_gravity_covers_more(cam, room, studies):
    four = coverage_study(cam, room, **KW)
    # the same geometry: the four-fixture map kept beside the gravity one is the plain study's
    np.testing.assert_array_equal(studies[2].fix_four, four.fix)
    f2, f3, f4 = (studies[k].fix for k in (2, 3, 4))
    assert np.all(f4 <= f3) and np.all(f3 <= f2)  # fewer fixtures needed: more fixes
    assert np.array_equal(f4, four.fix)  # four fixtures with gravity: the same poses
    assert f2.mean() > 1.5 * four.fix.mean()
    # every fix has an error, no other pose has one
    for s in studies.values():
        assert np.all(np.isfinite(s.errors_m[s.fix])) and np.all(np.isnan(s.errors_m[~s.fix]))
    s = studies[2].summary()
    assert s["gravity"] and s["min_fixtures"] == 2 and s["gravity_sigma_deg"] == 1.0
    assert s["mean_fix_fraction_four_no_gravity"] == pytest.approx(four.fix.mean())


def test_gravity_error_scale(studies):
    # poses with exactly two usable fixtures: the error is about the distance to the ceiling
    # (2.7 m) times the gravity error (1 degree per axis: mean 1.25 degrees)
    s = studies[2]
    two = s.fix & (s.usable == 2)
    e = s.errors_m[two].ravel()
    assert two.sum() >= 20
    assert 0.3 * 2.7 * np.radians(1.25) < np.mean(e) < 2.0 * 2.7 * np.radians(1.25)
    # four fixtures fix the tilt from the pixels: millimetres
    four = s.fix & (s.usable == 4)
    assert np.mean(s.errors_m[four]) < 0.2 * np.mean(e)


def test_vertical_pair_is_no_fix(cam):
    # two lights one above the other: with gravity the heading is free
    pair = FixtureMap(
        (
            Fixture(1, [0.0, -2.7, 0.0], 0.15, [0, 1, 0]),
            Fixture(2, [0.0, -2.2, 0.0], 0.1, [0, 1, 0]),
        ),
        up=[0, -1, 0],
    )
    res = coverage_study(
        cam,
        pair,
        u_range_m=(0.3, 0.3),
        v_range_m=(0, 0),
        tilt_max_deg=0,
        tilt_step_deg=1,
        gravity=True,
    )
    assert res.usable[0, 0, 0] == 2 and not res.fix.any()


def test_min_fixtures_checked(cam, room):
    with pytest.raises(ValueError, match="min_fixtures"):
        coverage_study(cam, room, min_fixtures=2, **KW)
    with pytest.raises(ValueError, match="min_fixtures"):
        coverage_study(cam, room, gravity=True, min_fixtures=5, **KW)
