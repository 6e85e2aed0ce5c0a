"""Error study and deployment planning (thesis chapter 4), geometry only.

Every study projects the fixtures' centres with an ideal camera onto an infinite image
plane, rounds them to whole pixels (the thesis' pixelisation; optional), perturbs what the
study asks for, solves PnP (:mod:`camvlp.geometry.pnp`) and measures how far the estimated camera
centre is from the true one.

* :func:`rounding_study`: camera on a grid over the floor at one orientation; the only error
  is the pixel rounding (thesis figure 4.2), optionally with Gaussian noise.
* :func:`forced_error_study`: a forced offset on one fixture's image coordinate (pixels) or
  world coordinate (metres), for several camera poses (figures 4.3 to 4.5).
* :func:`monte_carlo_study`: Gaussian noise on every fixture's image point and/or world
  point, many trials per pose (mean, median, 95th percentile).
* :func:`coverage_study`: where on the floor a fix is possible (at least four fixtures
  wholly in the image and spanning enough rows to decode; two or three when the camera
  knows gravity; in a site whose IDs repeat, fixtures that place the camera), over a range
  of tilts, and the expected error there.

Units: the study works in metres whatever the map's unit (converted with
:attr:`FixtureMap.unit_m`); errors are in metres; image quantities in pixels.  The floor is
the plane where the map's vertical coordinate is 0; "up" points from it towards the
fixtures, so in the thesis' room (y down, ceiling at y = -2.7 m) a camera height ``h``
means ``y = -h``.

The package, one module per study: :mod:`~camvlp.analysis.study.rounding`,
:mod:`~camvlp.analysis.study.forced` (image and world error),
:mod:`~camvlp.analysis.study.montecarlo`, :mod:`~camvlp.analysis.study.coverage` (with its
sweep over poses, :mod:`~camvlp.analysis.study.coverage_sweep`), what a camera sees of a
large site and which views its IDs leave ambiguous (:mod:`~camvlp.analysis.study.site_views`),
and
:mod:`~camvlp.analysis.study.common` (the solve and the error per pose they share).  Floor
grids come from :mod:`camvlp.sim.grid`, statistics from :mod:`camvlp.analysis.stats`; the
plots are in :mod:`camvlp.viz.study_plots` and the files in :mod:`camvlp.io.writers`.
"""

from __future__ import annotations

from camvlp.analysis.stats import error_stats
from camvlp.analysis.study.common import Progress, round_pixels, solve_positions
from camvlp.analysis.study.coverage import CoverageStudy, coverage_study
from camvlp.analysis.study.forced import ForcedErrorStudy, forced_error_study
from camvlp.analysis.study.montecarlo import MonteCarloStudy, monte_carlo_study
from camvlp.analysis.study.rounding import RoundingStudy, rounding_study
from camvlp.sim.grid import axis_values, floor_grid, set_height

__all__ = [
    "CoverageStudy",
    "ForcedErrorStudy",
    "MonteCarloStudy",
    "Progress",
    "RoundingStudy",
    "axis_values",
    "coverage_study",
    "error_stats",
    "floor_grid",
    "forced_error_study",
    "monte_carlo_study",
    "round_pixels",
    "rounding_study",
    "set_height",
    "solve_positions",
]
