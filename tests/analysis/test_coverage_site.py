"""The coverage study over a site: fixtures near each camera only, and IDs that repeat."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.analysis.study import coverage_sweep
from camvlp.analysis.study.coverage import coverage_study
from camvlp.geometry.disc import rim_points
from camvlp.model.camera import Camera
from camvlp.pipeline.identify.by_geometry import LIGHTS_NEEDED
from camvlp.sim.site import site_map

# a wide camera (f = 200 px over 320 x 240: 77 degrees across) 1.8 m under a ceiling of
# fixtures 1 m apart sees 3 to 6 of them whole; 100 kHz chips make the 18-chip frame 9 rows,
# so the discs (0.3 m: about 33 px) are decodable up to a few metres away
CAMERA = Camera.from_focal(320, 240, 200.0, row_time_s=20e-6)
STUDY = {
    "plane": "xy",
    "u_range_m": (1.0, 8.0),
    "v_range_m": (1.0, 8.0),
    "step_m": 1.0,
    "height_m": 1.2,
    "base_euler_deg": (0.0, 0.0, 0.0),
    "tilt_max_deg": 10.0,
    "tilt_step_deg": 10.0,
    "chip_rate_hz": 100_000.0,
    "noise_px": 0.0,
    "rounding": False,
}


def site(pattern: str):
    return site_map(10, 10, spacing=1.0, height=3.0, diameter=0.3, pattern=pattern, seed=2)


def test_a_site_swept_in_blocks_gives_what_one_sweep_gives(monkeypatch):
    whole = coverage_study(CAMERA, site("varied"), **STUDY)
    # 64 centres x 100 fixtures x 16 rim points: blocks of a few centres each, each against
    # the fixtures within reach of it
    monkeypatch.setattr(coverage_sweep, "POINTS_AT_ONCE", 5_000)
    fixtures = site("varied")
    rims = rim_points(fixtures.positions, np.full(100, 0.3), np.tile([0, 0, -1.0], (100, 1)), 16)
    centres = whole.positions_m.reshape(-1, 3)
    cells = coverage_sweep._cells(CAMERA, centres, rims, 10.8)
    blocks = coverage_sweep._blocks(CAMERA, np.eye(3), len(centres), 100, 16, cells)
    assert len(blocks) > 4 and max(cols.size for _, cols in blocks) < 100
    parts = coverage_study(CAMERA, site("varied"), **STUDY)
    np.testing.assert_array_equal(parts.usable, whole.usable)
    np.testing.assert_array_equal(parts.fix, whole.fix)
    np.testing.assert_array_equal(parts.ambiguous, whole.ambiguous)
    np.testing.assert_allclose(parts.errors_m, whole.errors_m, atol=1e-9)


def test_views_a_repeating_site_leaves_ambiguous_get_no_fix():
    periodic = coverage_study(CAMERA, site("periodic"), **STUDY)
    assert periodic.fix_four.sum() > 20  # the views see lights enough for a pose...
    assert periodic.fix.sum() == 0  # ...but the same IDs repeat every four steps
    assert periodic.ambiguous.sum() == periodic.fix_four.sum()
    assert periodic.summary()["reuse"] and periodic.summary()["fixes"] == 0


def test_a_varied_site_places_the_views_of_enough_lights():
    varied = coverage_study(CAMERA, site("varied"), **STUDY)
    assert varied.fix.sum() > 20
    assert np.all(varied.usable[varied.fix] >= LIGHTS_NEEDED)
    few = varied.fix_four & (varied.usable < LIGHTS_NEEDED)
    assert np.all(varied.ambiguous[few])  # four lights: too few to place in a site
    assert np.nanmax(varied.errors_m) < 1e-6  # no noise: the fixes are exact


@pytest.mark.parametrize("reuse", [False])
def test_a_room_has_no_ambiguity_to_report(reuse, thesis_camera_path, thesis_room_path):
    from camvlp.io import load_camera, load_map

    room = coverage_study(
        load_camera(thesis_camera_path), load_map(thesis_room_path), tilt_step_deg=15.0
    )
    assert room.ambiguous is None and room.summary()["ambiguous_views"] is None
    assert room.fix.sum() > 0
