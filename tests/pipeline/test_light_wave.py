"""A light's waveform separated from its shape, and the square wave fitted to it."""

from __future__ import annotations

import numpy as np
import pytest

import camvlp.pipeline.lamp.light_wave as light_wave_module
from camvlp.imaging.gray import to_gray
from camvlp.imaging.stripe_period import estimate_stripe_period
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.pipeline.decode.beacon import BeaconProfile, square_wave
from camvlp.pipeline.decode.beacon_match import stripes_period
from camvlp.pipeline.decode.frequency import decode_frequencies
from camvlp.pipeline.detect.candidates import detect_fixtures
from camvlp.pipeline.detect.disc import light_support
from camvlp.pipeline.lamp.light_wave import LightWave, separated_wave
from camvlp.sim.render import RenderSettings, render

ROW_TIME_S = 1 / 47_540.0


class Measured:
    """A light's stripes measured as the frequency decoder measures them: its waveform
    separated from its radial shape (:func:`separated_wave`), its period from the beacon
    model (:func:`stripes_period`); falsy with the separation's message when it fails."""

    def __init__(self, gray, support, ellipse, axis: str) -> None:
        got = separated_wave(gray, support, ellipse, axis)
        self.message = got.message if isinstance(got, LightWave) else ""
        self.centre = got.centre if isinstance(got, LightWave) else got[6]
        self.period_px = float("nan")
        if not self.message:
            profile = BeaconProfile(*got[:6])
            self.period_px = float(stripes_period(profile)[1][0])
            if not profile.usable:
                self.message = "too few lines with signal"

    def __bool__(self) -> bool:
        return not self.message


def fitted_period(lines, signal, weight, *bounds) -> float:
    """The period (lines) the beacon model fits to a line profile (NaN for too few lines)."""
    return float(stripes_period(BeaconProfile(lines, signal, weight, *bounds))[1][0])


def _square(lines, period, phase, window, n=4000):
    """A 50 % square wave (high first from ``phase``) averaged over a centred window, by
    brute force (``n`` samples per window), independent of the module's closed form."""
    t = lines[:, None] - phase + window * (np.arange(n) / (n - 1) - 0.5)[None, :]
    return (np.mod(t, period) < 0.5 * period).mean(axis=1)


def test_a_grid_costs_what_its_waves_cost_kept_or_shared_between_models():
    # a grid is costed once per profile and its waves shared with the flat model's profile
    # (the stripes' period search tries the same grids with both): every cost must be what
    # the waves cost computed afresh, grids of other windows or periods kept apart
    rng = np.random.default_rng(11)
    lines = np.arange(60.0)
    level = 0.5 + 0.4 * square_wave(lines, 14.0, 3.0, 2.0) + 0.02 * rng.standard_normal(60)
    full = BeaconProfile(lines, level, np.ones(60), [60.0, 61.0], [0.95, 0.97], [1.0, 1.0])
    flat = full.with_degrees(0, 0)
    periods = np.exp(np.linspace(np.log(12.0), np.log(16.0), 7))
    waves: dict = {}
    for windows in ((0.2, 0.6), (0.1, 0.4, 1.0)):
        for profile in (full, flat, full):  # the flat one on the full one's waves, then kept
            got = profile.grid(periods, 8, windows, waves=waves)
            p = periods[:, None, None, None, None]
            ph = (np.arange(8) / 8)[None, :, None, None, None] * p
            win = np.maximum(np.asarray(windows)[None, None, :, None, None] * 0.5 * p, 1.0)
            fresh = BeaconProfile(lines, level, np.ones(60), [60.0, 61.0], [0.95, 0.97], [1.0, 1.0])
            fresh = fresh.with_degrees(*profile.degrees)
            assert np.array_equal(got, fresh.costs(*fresh.wave(p, ph, win, 0.5)))
            assert got.shape == (7, 8, len(windows), 1)
    assert len(waves) == 2
    assert not np.array_equal(full.grid(periods, 8, (0.2, 0.6)), flat.grid(periods, 8, (0.2, 0.6)))
    assert full.best(periods[:3], 8, (0.2, 0.6))[0] >= full.best(periods, 8, (0.2, 0.6))[0]
    with pytest.raises(ValueError):  # what a search keeps is not changed by its callers
        full.grid(periods, 8, (0.2, 0.6))[0] = 0.0


def test_the_integrated_wave_is_the_brute_force_average():
    # the closed form (a trapezoid around each edge) against the wave averaged by brute force,
    # over periods, phases and windows up to half a period, the grids' shapes included
    rng = np.random.default_rng(3)
    lines = np.arange(-30.0, 90.0, 0.7)
    for _ in range(20):
        period = rng.uniform(2.5, 60.0)
        phase = rng.uniform(-2.0 * period, 2.0 * period)
        window = rng.uniform(0.02, 0.5) * period
        exact = _square(lines, period, phase, window)
        np.testing.assert_allclose(square_wave(lines, period, phase, window), exact, atol=1e-3)
    periods = np.array([5.0, 13.0])[:, None, None, None]
    windows = np.array([0.1, 0.5])[None, None, :, None] * periods
    phases = np.array([0.0, 2.5, 7.0])[None, :, None, None]
    grid = square_wave(lines, periods, phases, windows)
    assert grid.shape == (2, 3, 2, lines.size)
    for i, j, k in np.ndindex(2, 3, 2):
        exact = _square(lines, periods[i, 0, 0, 0], phases[0, j, 0, 0], windows[i, 0, k, 0])
        np.testing.assert_allclose(grid[i, j, k], exact, atol=1e-3)


@pytest.mark.parametrize("seed", range(4))
def test_the_beacon_model_recovers_the_period_of_1_6_periods(seed):
    rng = np.random.default_rng(seed)
    period = rng.uniform(10.0, 24.0)
    phase = rng.uniform(0.0, period)
    window = rng.uniform(0.2, 0.4) * period
    lines = np.arange(int(1.6 * period), dtype=float)  # 1.6 periods
    signal = 30.0 + 200.0 * _square(lines, period, phase, window)
    signal += rng.normal(0.0, 2.0, lines.size)
    assert fitted_period(lines, signal, np.ones(lines.size)) == pytest.approx(period, rel=0.005)


def test_fit_square_wave_uses_clipped_lines_as_bounds():
    # the high level is clipped: only the dips are measured; the clipped lines say the
    # wave was at least at the clip there.  Without them a long dip-less stretch fits a
    # longer period as well as the true one.
    period, phase, window = 14.0, 3.0, 5.0
    lines = np.arange(34.0)
    wave = 20.0 + 400.0 * _square(lines, period, phase, window)
    clipped = wave >= 200.0
    w = (~clipped).astype(float)
    p = fitted_period(
        lines[~clipped],
        wave[~clipped],
        w[~clipped],
        lines[clipped],
        200.0 + 0 * lines[clipped],
        1.0 + 0 * lines[clipped],
    )
    assert p == pytest.approx(period, rel=0.01)


@pytest.mark.parametrize(("n_lines", "period"), [(60, 8.0), (60, 3.3), (200, 8.0)])
def test_short_periods_are_not_mistaken_for_a_multiple(n_lines, period):
    # lines binned 4 at a time average a period of 8 over its halves and look flat: a
    # period of 40 fitted them more cheaply than the true one fitted the lines themselves
    rng = np.random.default_rng(0)
    lines = np.arange(float(n_lines))
    signal = 30.0 + 200.0 * _square(lines, period, 1.3, 0.3 * period, n=400)
    signal += rng.normal(0.0, 2.0, lines.size)
    assert fitted_period(lines, signal, np.ones(lines.size)) == pytest.approx(period, rel=0.002)


def test_too_few_lines_give_nan():
    assert not BeaconProfile(np.arange(5.0), np.ones(5), np.ones(5)).usable
    assert np.isnan(fitted_period(np.arange(5.0), np.ones(5), np.ones(5)))


def test_a_region_of_a_few_lines_gives_no_period():
    # six lines of a light whose period is 14: a period of 2.5 fitted them as well as any
    gray, support, _ = _striped_disc(size=80)
    wave = Measured(gray[37:43], support[37:43], ((40.3, 2.7), (40.0, 40.0), 0.0), "rows")
    assert not wave and "too few" in wave.message


def _one_light(periods: float, **style) -> tuple[np.ndarray, FixtureMap, Camera, object]:
    """One 2000 Hz light ``periods`` stripe periods across, seen straight up from 2.7 m."""
    period_px = 1.0 / (2000.0 * ROW_TIME_S)
    d_m = periods * period_px * 2.7 / 1000.0
    light = Fixture(
        1, np.array([0.0, -2.7, 0.0]), d_m, np.array([0.0, 1.0, 0.0]), frequency_hz=2000.0
    )
    fmap = FixtureMap((light,), mode="frequency")
    camera = Camera.from_focal(200, 200, 1000.0, row_time_s=ROW_TIME_S)
    pose = Pose.from_euler([0.01, 0.0, -0.02], [90.0, 0.0, 0.0])
    photo = render(camera, fmap, pose, RenderSettings(row_time_s=ROW_TIME_S, **style))
    return photo, fmap, camera, period_px


@pytest.mark.parametrize("seed", range(3))
def test_the_waveform_is_free_of_a_hot_core(seed):
    # a hot core five times the rim's brightness, not clipped: a periodic fit of the row
    # means sees the core as much as the stripes; the separated waveform does not
    style = dict(exposure_s=0.3 / 2000.0, brightness=0.15, core=4.0, read_noise=0.005, seed=seed)
    photo, _, _, period_px = _one_light(1.6, **style)
    (blob,) = detect_fixtures(photo.image).blobs
    gray = to_gray(photo.image[blob.box[1] : blob.box[3], blob.box[0] : blob.box[2]])
    support = light_support(gray, blob.mask, "rows")
    ellipse = ((blob.pixel[0] - blob.box[0], blob.pixel[1] - blob.box[1]), blob.axes_px, 0.0)
    wave = Measured(gray, support, ellipse, "rows")
    assert wave, wave.message
    assert wave.period_px == pytest.approx(period_px, rel=0.01)
    centre = wave.centre + blob.box[:2]
    assert np.hypot(*(centre - photo.fixtures[0].pixel)) < 0.5


def test_lights_showing_one_and_a_half_periods_are_within_one_percent():
    # unclipped lights with stripe edges a few rows long, 1.5 periods across: the periodic
    # fit of the row means was 2 % off at the median; the square wave over every edge is
    # within 1 % for nearly all of them
    errors, old = [], []
    for seed in range(10):
        style = dict(exposure_s=0.25 / 2000.0, brightness=0.8, read_noise=0.02, seed=seed)
        photo, fmap, camera, period_px = _one_light(1.5, **style)
        det = detect_fixtures(photo.image)
        gray = to_gray(photo.image)
        rois = [gray[b.box[1] : b.box[3], b.box[0] : b.box[2]] for b in det.blobs]
        _, hz, _, _, _ = decode_frequencies(det.blobs, rois, "rows", camera, fmap)
        errors.append(abs(hz[0] / 2000.0 - 1))
        est = estimate_stripe_period(rois[0], det.blobs[0].mask, "rows")
        old.append(abs(est.period_px / period_px - 1))
    assert np.median(errors) < 0.005 and np.mean(np.array(errors) < 0.01) >= 0.9, errors
    assert np.median(errors) < np.median(old)


def _striped_disc(
    period: float = 14.0, amp: float = 150.0, size: int = 80, ratio: float = 1.0, seed: int = 0
):
    """A synthetic light (a cone-shaped disc of radius 20 px, axis ratio ``ratio`` across the
    readout) with stripes of ``period`` rows, on a background of 20; (gray, support, ellipse)."""
    rng = np.random.default_rng(seed)
    cx, cy, r = 0.5 * size + 0.3, 0.5 * size - 0.3, 20.0
    yy, xx = np.mgrid[:size, :size].astype(float)
    rr = np.hypot((xx - cx) / (r * ratio), (yy - cy) / r)
    shape = np.clip(1.5 - rr, 0.0, 1.0) * (rr < 1)
    wave = 0.1 + 0.9 * ((yy % period) < 0.5 * period)
    gray = np.clip(20.0 + amp * shape * wave + rng.normal(0.0, 2.0, shape.shape), 0, 255)
    return gray, rr < 1, ((cx, cy), (2 * r * ratio, 2 * r), 0.0)


def test_a_synthetic_disc_is_measured_in_rows_and_in_columns():
    gray, support, ((cx, cy), (aw, ah), _) = _striped_disc()
    rows = Measured(gray, support, ((cx, cy), (aw, ah), 0.0), "rows")
    cols = Measured(gray.T, support.T, ((cy, cx), (ah, aw), 90.0), "columns")
    assert rows and cols
    assert rows.period_px == pytest.approx(14.0, rel=0.01)
    assert cols.period_px == pytest.approx(rows.period_px, rel=1e-6)
    np.testing.assert_allclose(cols.centre, rows.centre[::-1], atol=1e-6)  # [x, y] of each
    assert np.hypot(rows.centre[0] - cx, rows.centre[1] - cy) < 0.5


@pytest.mark.parametrize("bad", ["centre", "axes", "angle"])
def test_an_outline_that_is_not_finite_fails_with_a_message(bad):
    gray, support, ((cx, cy), axes, angle) = _striped_disc()
    ellipse = {
        "centre": ((float("nan"), cy), axes, angle),
        "axes": ((cx, cy), (float("nan"), axes[1]), angle),
        "angle": ((cx, cy), axes, float("nan")),
    }[bad]
    wave = Measured(gray, support, ellipse, "rows")
    assert not wave and "not finite" in wave.message


def test_a_degenerate_outline_costs_no_more_than_a_round_one():
    # an outline with an axis of 0 (its ratio infinite) once stretched the radial bins to
    # hundreds of thousands and took seconds and gigabytes
    import tracemalloc

    gray, support, (centre, axes, angle) = _striped_disc()
    tracemalloc.start()
    wave = Measured(gray, support, (centre, (0.0, axes[1]), angle), "rows")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert wave and wave.period_px == pytest.approx(14.0, rel=0.01)
    assert peak < 30e6, peak


def test_a_disc_clipped_all_over_fails_instead_of_fitting_the_background():
    gray, support, ellipse = _striped_disc()
    gray[support] = 255.0
    wave = Measured(gray, support, ellipse, "rows")
    assert not wave and "clipped" in wave.message


def test_a_steady_light_is_refused_instead_of_fitted_with_a_long_period():
    from camvlp.pipeline.decode.beacon_match import hold_against

    gray, support, ellipse = _striped_disc(period=1e9)
    got = separated_wave(gray, support, ellipse, "rows")
    test = hold_against(BeaconProfile(*got[:6]), [14.0, 20.0])
    assert test.index is None and test.reason


def test_a_pixel_that_is_not_finite_is_left_out():
    gray, support, ellipse = _striped_disc()
    gray[2, 2] = np.nan  # in the background: its median was NaN, and every pixel with it
    gray[40, 40] = np.inf
    wave = Measured(gray, support, ellipse, "rows")
    assert wave and wave.period_px == pytest.approx(14.0, rel=0.01)


def test_a_light_exposed_over_whole_periods_is_left_unidentified_with_its_reason():
    # exposed over three whole periods the light looks steady: its waveform shows under one
    # period, and the periodic fit over the disc must not be asked instead (it found 2892 Hz
    # and named the map's 3000 Hz light)
    photo, fmap, camera, _ = _one_light(3.0, exposure_s=3.0 / 2000.0, brightness=20.0, seed=0)
    other = Fixture(
        2, np.array([5.0, -2.7, 0.0]), 0.1, np.array([0.0, 1.0, 0.0]), frequency_hz=3000.0
    )
    fmap = FixtureMap((*fmap.fixtures, other), mode="frequency")
    det = detect_fixtures(photo.image)
    gray = to_gray(photo.image)
    rois = [gray[b.box[1] : b.box[3], b.box[0] : b.box[2]] for b in det.blobs]
    decodes, _, _, _, _ = decode_frequencies(det.blobs, rois, "rows", camera, fmap)
    assert len(decodes) == 1 and decodes[0].id is None
    assert "too few" in decodes[0].reason or "not a square wave" in decodes[0].reason


@pytest.mark.parametrize(("period", "n_lines"), [(3.3, 400), (2.6, 200), (5.0, 300)])
def test_a_short_period_over_many_periods(period, n_lines):
    # over a hundred periods the coarse 3 % period steps lose the phase; the search also
    # starts from the spectrum's peak (3.3 lines over 400 came out 3 times too long before)
    rng = np.random.default_rng(7)
    lines = np.arange(float(n_lines))
    signal = 20.0 + 200.0 * _square(lines, period, 1.0, 1.0) + rng.normal(0.0, 3.0, n_lines)
    assert fitted_period(lines, signal, np.ones(n_lines)) == pytest.approx(period, rel=1e-3)


@pytest.mark.parametrize("iters", [2, 12])
def test_the_shape_fit_is_the_same_on_the_cells_that_hold_pixels(monkeypatch, iters):
    # a big light's fine bins over a few thousand pixels leave most (line, knot) cells
    # empty: the sums kept per cell that holds a pixel fit the same shape and stripes
    rng = np.random.default_rng(4)
    n = 3000
    line = rng.integers(0, 400, n)
    rho = rng.uniform(0.0, 400.0, n)
    value = 50.0 * np.exp(-rho / 150.0) * (1.0 + 0.5 * (line % 7 > 3)) + rng.normal(0, 1, n)
    monkeypatch.setattr(light_wave_module, "_DENSE_CELLS_PER_PIXEL", 10**9)
    dense = light_wave_module.aggregate(rho, line, value, 400, 0.5)
    monkeypatch.setattr(light_wave_module, "_DENSE_CELLS_PER_PIXEL", 0)
    cells = light_wave_module.aggregate(rho, line, value, 400, 0.5)
    assert isinstance(cells[1], light_wave_module.Cells) and not isinstance(
        dense[1], light_wave_module.Cells
    )
    assert cells[0] == dense[0]  # the same knots
    for a, b in zip(
        light_wave_module.shape_fit(dense, None, iters),
        light_wave_module.shape_fit(cells, None, iters),
        strict=True,
    ):
        np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9 * float(np.max(np.abs(a))))
