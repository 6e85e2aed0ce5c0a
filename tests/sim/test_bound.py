"""The Cramér-Rao bound of a light's frequency (camvlp.sim.bound)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import least_squares

from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.bound import frequency_bounds, frequency_intervals, share_within
from camvlp.sim.render import RenderSettings, light_patches

ROW_TIME_S = 1.0 / 47_540.0
FREQ_HZ = 2000.0
POSE = Pose.from_euler([0.01, 0.0, -0.02], [90.0, 0.0, 0.0])


def _scene(periods: float) -> tuple[Camera, FixtureMap]:
    """One 2000 Hz light ``periods`` stripe periods across, seen straight up from 2.7 m."""
    period_px = 1.0 / (FREQ_HZ * ROW_TIME_S)
    d_m = periods * period_px * 2.7 / 1000.0
    light = Fixture(
        1, np.array([0.0, -2.7, 0.0]), d_m, np.array([0.0, 1.0, 0.0]), frequency_hz=FREQ_HZ
    )
    camera = Camera.from_focal(160, 160, 1000.0, row_time_s=ROW_TIME_S)
    return camera, FixtureMap((light,), mode="frequency")


def _settings(**kw) -> RenderSettings:
    base = dict(
        row_time_s=ROW_TIME_S,
        exposure_s=1.5 * ROW_TIME_S,
        brightness=0.8,
        full_well_e=0.0,
        read_noise=0.02,
        seed=3,
    )
    return RenderSettings(**(base | kw))


def test_the_bound_matches_the_spread_of_a_maximum_likelihood_fit():
    # Gaussian read noise only, nothing clipped: the least-squares fit of the light's own
    # model (frequency, phase, exposure, brightness, ambient, off level; its shape known) to
    # the three colour channels is the maximum-likelihood estimate, whose spread the bound
    # must match
    camera, fmap = _scene(1.5)
    s = _settings().resolved(camera)
    (light,) = light_patches(camera, fmap, POSE, s)
    rows = s.readout.by_rows

    def model(x: np.ndarray) -> np.ndarray:
        scale, phase, exposure, brightness, ambient, off = x
        moved = dataclasses.replace(light, chip_s=light.chip_s / scale, phase_s=phase)
        on = moved.on_fraction(s.row_time_s, exposure, 0.0)
        on = off + (1.0 - off) * on
        return ambient + brightness * light.shape * (on[:, None] if rows else on[None, :])

    truth = np.array([1.0, light.phase_s, s.exposure_s, s.brightness, s.ambient, 0.0])
    clean = model(truth)
    assert clean.max() < 1.0  # nothing clipped: the bound's Gaussian model holds
    rng = np.random.default_rng(7)
    steps = np.array([1e-3, 1e-6, 1e-6, 1e-3, 1e-3, 1e-3])
    errors = []
    for _ in range(40):
        noisy = clean[..., None] + rng.normal(0.0, s.read_noise, (*clean.shape, 3))
        fit = least_squares(
            lambda x, y=noisy: (model(x)[..., None] - y).ravel(), truth, x_scale=steps
        )
        errors.append(fit.x[0] - 1.0)
    bound = frequency_bounds(camera, fmap, POSE, s)[0]
    spread = float(np.std(errors))
    # 40 draws: the sample deviation is within about +-25 % of the true one
    assert 0.7 * bound < spread < 1.35 * bound, (spread, bound)


def test_the_bound_grows_with_the_noise_and_shrinks_with_the_periods_shown():
    camera, fmap = _scene(2.0)
    quiet = frequency_bounds(camera, fmap, POSE, _settings(read_noise=0.02))[0]
    loud = frequency_bounds(camera, fmap, POSE, _settings(read_noise=0.04))[0]
    assert loud / quiet == pytest.approx(2.0, rel=0.02)  # read noise dominates quantisation
    wide_camera, wide_map = _scene(4.0)
    wide = frequency_bounds(wide_camera, wide_map, POSE, _settings(read_noise=0.02))[0]
    assert wide < 0.5 * quiet


def test_clipping_costs_precision():
    camera, fmap = _scene(2.0)
    dim = frequency_bounds(camera, fmap, POSE, _settings(brightness=0.8))[0]
    # eight times brighter: without clipping the bound would shrink eightfold
    bright = frequency_bounds(camera, fmap, POSE, _settings(brightness=6.4))[0]
    assert bright > dim / 8.0 * 1.5


def test_a_dark_light_tells_nothing():
    camera, fmap = _scene(2.0)
    assert frequency_bounds(camera, fmap, POSE, _settings(brightness=0.0))[0] == np.inf


def test_a_light_out_of_view_has_no_bound_and_codes_must_be_frequencies():
    camera, fmap = _scene(2.0)
    away = Pose.from_euler([0.0, 0.0, 0.0], [-90.0, 0.0, 0.0])  # looking down
    assert np.isnan(frequency_bounds(camera, fmap, away, _settings())[0])
    manchester = FixtureMap(fmap.fixtures, mode="manchester")
    with pytest.raises(ValueError, match="frequency"):
        frequency_bounds(camera, manchester, POSE, _settings())


def test_share_within():
    assert share_within(np.array([0.01 / 1.959964]))[0] == pytest.approx(0.95, abs=1e-4)
    out = share_within(np.array([np.inf, np.nan, 1e-6]))
    assert out[0] == 0.0 and np.isnan(out[1]) and out[2] == pytest.approx(1.0)


def test_stripes_sharper_than_a_line_leave_the_frequency_undetermined():
    # exposed for 0.6 of a row, each stripe edge is caught by one line at most: a frequency
    # 0.5 % lower with a shorter exposure (the edges moved in proportion) gives every line
    # the same on-fraction, so the same pixels; the bound must not claim a hundredth of that
    camera, fmap = _scene(2.0)
    s = _settings(exposure_s=0.6 * ROW_TIME_S, read_noise=0.002).resolved(camera)
    (light,) = light_patches(camera, fmap, POSE, s)
    on = light.on_fraction(s.row_time_s, s.exposure_s)

    def on_at(scale: float, x: np.ndarray) -> np.ndarray:
        moved = dataclasses.replace(light, chip_s=light.chip_s / scale, phase_s=x[0])
        return moved.on_fraction(s.row_time_s, x[1])

    for scale in (0.995, 1.002):
        fit = least_squares(
            lambda x, k=scale: on_at(k, x) - on, [light.phase_s, s.exposure_s], x_scale=1e-6
        )
        assert np.abs(fit.fun).max() < 1e-6 and fit.x[1] > 0.0
    assert frequency_bounds(camera, fmap, POSE, s)[0] == np.inf
    lo, hi = frequency_intervals(camera, fmap, POSE, s)[0]
    assert lo <= -0.005 and hi >= 0.002


def test_a_light_exposed_over_rows_has_a_narrow_interval():
    # exposed for 1.5 rows, every edge shows in two lines or more: the frequencies the
    # pixels cannot tell apart lie within a few bounds' standard deviations
    camera, fmap = _scene(2.0)
    s = _settings(read_noise=0.002)
    sigma = frequency_bounds(camera, fmap, POSE, s)[0]
    lo, hi = frequency_intervals(camera, fmap, POSE, s)[0]
    assert np.isfinite(sigma) and -0.001 <= lo <= 0.0 <= hi <= 0.001
    assert hi - lo <= 10.0 * sigma + 0.001  # the interval's steps are 0.05 %
