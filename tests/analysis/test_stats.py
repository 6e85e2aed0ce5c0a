"""Tests for camvlp.analysis.stats: the statistics the study and the evaluation share."""

from __future__ import annotations

import math

import pytest

from camvlp.analysis.stats import error_stats, json_number, summary_stats


def test_statistics_leave_out_failures():
    s = summary_stats([3.0, math.nan, 4.0, 5.0, math.inf])
    assert (s["mean"], s["median"], s["max"]) == (4.0, 4.0, 5.0)
    assert s["p95"] == pytest.approx(4.9)  # 4 + 0.9 * (5 - 4)
    assert summary_stats([math.nan]) == {"mean": None, "median": None, "p95": None, "max": None}
    assert summary_stats([1 / 3], digits=3)["mean"] == 0.333


def test_error_stats_count_poses_and_failures():
    s = error_stats([[0.001, math.nan], [0.003, 0.002]])
    assert (s["poses"], s["failures"]) == (4, 1)
    assert s["mean_error_m"] == pytest.approx(0.002) and s["max_error_m"] == 0.003
    assert error_stats([math.nan])["median_error_m"] is None
    assert json_number(math.nan) is None and json_number(2 / 3) == 0.666667
