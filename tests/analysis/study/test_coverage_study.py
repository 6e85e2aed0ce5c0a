"""Tests for camvlp.analysis.study.coverage: the thesis' chapter 4 findings.

Bounds come from the thesis text (figures 3.8, 3.10, 4.2 to 4.5) or from first-order
reasoning, not from this code's output.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from study_helpers import cam, room  # noqa: F401  (fixtures)

from camvlp.analysis.study import (
    coverage_study,
)
from camvlp.model.fixtures import Fixture, FixtureMap

# ---------------------------------------------------------------------------- coverage


def _max_tilts(res):
    e, fix = res.euler_deg, res.fix[0, 0]
    about_x = np.abs(e[(e[:, 1] == 0) & fix, 0] - 90).max()
    about_y = np.abs(e[(e[:, 0] == 90) & fix, 1]).max()
    return about_x, about_y


def test_coverage_tilt_limits_match_thesis_chapter_3(cam, room):
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=18, tilt_step_deg=1, min_frames=0)
    # thesis fig. 3.8: from the floor about 12 deg about x and 15 about y
    tx, ty = _max_tilts(coverage_study(cam, room, height_m=0.0, **kw))
    assert 10 <= tx <= 14 and 13 <= ty <= 17
    assert ty > tx  # the sensor is wider than tall and the layout too
    # fig. 3.10: from 1 m up about 4 and 6 deg
    tx, ty = _max_tilts(coverage_study(cam, room, height_m=1.0, **kw))
    assert 3 <= tx <= 5 and 5 <= ty <= 7


def test_coverage_needs_enough_rows_to_decode(cam, room):
    # a 15 cm disc 2.7 m away spans 3912 * 0.15 / 2.7 = 217 rows; 18 chips at 4 kHz and
    # 20 us per row last 225 rows per frame -> undecodable; at 10 kHz 90 rows -> fine
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1)
    ok = coverage_study(cam, room, chip_rate_hz=10_000, **kw)
    slow = coverage_study(cam, room, chip_rate_hz=4_000, **kw)
    assert ok.frame_rows == pytest.approx(90.0)
    assert ok.fix.all() and not slow.fix.any()
    assert slow.usable.max() == 0
    assert ok.summary()["mean_error_m"] < 0.02


def test_coverage_rejects_collinear_fixtures(cam):
    line = FixtureMap(
        tuple(
            Fixture(i, [x, -2.7, 0.0], 0.15)
            for i, x in zip((1, 2, 3, 4), (-0.3, -0.1, 0.1, 0.3), strict=True)
        )
    )
    res = coverage_study(
        cam, line, u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1
    )
    assert res.usable[0, 0, 0] == 4 and not res.fix.any()


def test_coverage_map_shape_and_summary(cam, room):
    res = coverage_study(cam, room, step_m=1.0, tilt_max_deg=10, tilt_step_deg=10, seed=1)
    assert res.fix.shape == (3, 3, 9) and res.errors_m.shape == (3, 3, 9, 1)
    s = res.summary()
    assert 0 < s["mean_fix_fraction"] <= 1 and s["orientations"] == 9
    assert np.all(np.isnan(res.errors_m[~res.fix]))
    assert np.all(np.isfinite(res.errors_m[res.fix]))


def test_coverage_needs_diameters(cam):
    bare = FixtureMap(
        tuple(
            Fixture(i, p)
            for i, p in zip(
                (1, 2, 3, 4),
                [(1, -2.7, 1), (1, -2.7, -1), (-1, -2.7, -1), (-1, -2.7, 1)],
                strict=True,
            )
        )
    )
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1)
    with pytest.raises(ValueError, match="fixture 1 has no diameter"):
        coverage_study(cam, bare, **kw)
    assert coverage_study(cam, bare, default_diameter_m=0.15, **kw).fix.all()


@pytest.mark.parametrize("axis", ["rows", "columns"])
def test_coverage_reads_a_reversed_readout_along_the_same_axis(cam, room, axis):
    # fy half of fx: a 15 cm disc 2.7 m away spans about 217 columns but only 109 rows; 1.5
    # frames are 135 rows (18 chips at 10 kHz, 20 us rows), so the readout's axis decides
    k = cam.matrix.copy()
    k[1, 1] = 0.5 * k[0, 0]
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1, min_frames=1.5)
    usable = {}
    for readout in (axis, f"{axis}-reversed"):
        wide = dataclasses.replace(cam, matrix=k, readout=readout)
        usable[readout] = int(coverage_study(wide, room, **kw).usable.max())
    assert usable[axis] == usable[f"{axis}-reversed"]
    assert usable[axis] == (4 if axis == "columns" else 0)
