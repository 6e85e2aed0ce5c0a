"""Tests for camvlp.analysis.study.rounding: the thesis' chapter 4 findings.

Bounds come from the thesis text (figures 3.8, 3.10, 4.2 to 4.5) or from first-order
reasoning, not from this code's output.
"""

from __future__ import annotations

import numpy as np
import pytest
from study_helpers import cam, room  # noqa: F401  (fixtures)

from camvlp.analysis.study import (
    rounding_study,
)
from camvlp.model.fixtures import Fixture, FixtureMap


def _scaled_map(fmap: FixtureMap, units: str, factor: float) -> FixtureMap:
    return FixtureMap(
        tuple(
            Fixture(f.id, f.position * factor, f.diameter * factor, f.normal) for f in fmap.fixtures
        ),
        units=units,
    )


def _z_up_map(fmap: FixtureMap) -> FixtureMap:
    """The thesis' room in a z-up frame: (x, y, z) -> (x, z, -y), a proper rotation."""
    m = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    return FixtureMap(
        tuple(Fixture(f.id, m @ f.position, f.diameter, m @ f.normal) for f in fmap.fixtures)
    )


# --------------------------------------------------------------------------- rounding


THESIS_FIG_4_2_MM = {(90, 0, 0): 1.1, (90, 20, 0): 1.4, (70, 0, 0): 1.5, (70, 20, 0): 1.6}


@pytest.mark.parametrize(("euler", "thesis_mm"), list(THESIS_FIG_4_2_MM.items()))
def test_rounding_reproduces_thesis_figure_4_2(cam, room, euler, thesis_mm):
    res = rounding_study(cam, room, euler_deg=euler)  # the thesis' floor, 21 x 21
    assert res.errors_m.shape == (21, 21, 1)
    assert res.summary()["failures"] == 0
    assert abs(res.mean_error_m * 1e3 - thesis_mm) <= 0.4 * thesis_mm
    assert res.max_error_m < 0.01  # "always in the order of millimetres"


def test_a_camera_in_the_fixtures_plane_is_a_failure_not_a_huge_error(cam, room):
    """At the ceiling's height the fixtures lie on the camera plane: none is imaged, so every
    pose fails (their rotation left depths of 1e-16 m, projected 1e16 focal lengths out and
    solved into errors of 1e20 mm)."""
    res = rounding_study(cam, room, euler_deg=(90, 0, 0), step_m=0.5, height_m=2.7)
    assert res.summary()["failures"] == res.errors_m.size
    assert not np.any(np.isfinite(res.errors_m))


def test_rounding_error_grows_with_tilt(cam, room):
    # thesis: tilting in both axes gives the largest mean error (fig. 4.2d vs 4.2a)
    level = rounding_study(cam, room, euler_deg=(90, 0, 0)).mean_error_m
    both = rounding_study(cam, room, euler_deg=(70, 20, 0)).mean_error_m
    assert both > level


def test_without_rounding_the_error_vanishes(cam, room):
    res = rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=0.5, rounding=False)
    assert res.max_error_m < 1e-6


def test_rounding_same_in_cm_map_and_z_up_frame(cam, room):
    ref = rounding_study(cam, room, euler_deg=(90, 0, 0), step_m=0.25, height_m=0.5)
    in_cm = rounding_study(
        cam, _scaled_map(room, "cm", 100.0), euler_deg=(90, 0, 0), step_m=0.25, height_m=0.5
    )
    np.testing.assert_allclose(in_cm.errors_m, ref.errors_m, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(in_cm.positions_m, ref.positions_m)
    # same room, z up: the camera looking up (+z) is theta = (0, 0, 0); floor plane xy
    z_up = rounding_study(
        cam, _z_up_map(room), euler_deg=(0, 0, 0), plane="xy", step_m=0.25, height_m=0.5
    )
    # same pixels; the solver's convergence depends slightly on the frame (microns)
    np.testing.assert_allclose(z_up.errors_m, ref.errors_m, rtol=0, atol=2e-5)
    assert np.allclose(z_up.positions_m[..., 2], 0.5)  # up is +z here
    assert np.allclose(ref.positions_m[..., 1], -0.5)  # and -y in the thesis' frame


def test_rounding_monte_carlo_is_seeded(cam, room):
    kw = dict(euler_deg=(90, 0, 0), step_m=1.0, noise_px=0.5, trials=5)
    a = rounding_study(cam, room, seed=1, **kw)
    b = rounding_study(cam, room, seed=1, **kw)
    c = rounding_study(cam, room, seed=2, **kw)
    assert a.errors_m.shape == (3, 3, 5)
    np.testing.assert_array_equal(a.errors_m, b.errors_m)
    assert not np.array_equal(a.errors_m, c.errors_m)
    assert a.summary()["trials"] == 5


def test_solvers_agree_where_they_should(cam, room):
    # iterative and SQPnP both minimise the reprojection error: same answer to a few %
    it = rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=0.25).mean_error_m
    sq = rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=0.25, solver="sqpnp")
    assert sq.mean_error_m == pytest.approx(it, rel=0.1)


def test_rounding_study_runs_the_locators_own_pose_path(cam, room):
    kw = dict(euler_deg=(90, 0, 0), u_range_m=(-0.2, 0.2), v_range_m=(-0.2, 0.2), step_m=0.2)
    ours = rounding_study(cam, room, solver="locate", **kw)
    opencv = rounding_study(cam, room, solver="iterative", **kw)
    assert np.all(np.isfinite(ours.errors_m))
    # both reach the rounding floor (about a millimetre), not the same numbers
    assert np.nanmean(ours.errors_m) < 0.005 and np.nanmean(opencv.errors_m) < 0.005
    assert ours.summary()["solver"] == "locate"
