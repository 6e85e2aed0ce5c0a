"""Precision of frequency-coded lights: the measured frequency and centre of each light.

Renders frequency-coded lights (50 % square waves, 2000 to 4000 Hz, at a real phone's
47,540 rows/s, so 11.9 to 23.8 rows per period) over a seeded sweep: periods shown across the
disc 1.5 to 8; plain hard stripes (saturated, and dim), soft stripes, a hot core with a
halo, a hot core off the centre (``off-core``: 0.4 of the radius off, each light its own
way, the rim at half of full scale and the core four times that); exposure 0.05 to 0.35 of the
shortest (4000 Hz) period; clean, noisy, and noisy JPEG
(quality 80); the readout down the rows and, reversed, along the columns.  Each photo shows
four lights in a 2 x 2 grid seen from 2.7 m below; ``camvlp.locate`` measures them.  Prints,
per light style and periods shown, the frequency error (median, worst, and the share of
lights within 1 %) and the centre error (median and worst, px, against the projected disc
centre), then per exposure, noise and readout, and overall, with how many lights showing 1.5
periods or more came out within 1 %, and the time ``locate`` took per photo.

Each light is also measured against the best any method could do: the Cramer-Rao bound of
its frequency from the renderer's own physics and noise, JPEG's error included
(:func:`camvlp.sim.bound.frequency_bounds`).  The columns "bound" give its median standard
deviation and the share of lights an unbiased measurement that reached it would bring within
1 %; the last lines, how many that is over the whole sweep and the measured errors over the
bound (an efficient measurement's median is 0.67).

With ``--limits``, each light off by 1 % or more is also checked globally: the frequencies
its noise-free pixels fit within one standard deviation of their noise
(:func:`camvlp.sim.bound.frequency_intervals`; stripes sharper than a line fit a whole range
of them, which the local bound, infinite there, does not tell apart).  Each such light is
listed as a limit (its interval reaches 1 % off or more) or not, and the run ends with "N of
M within 1 %, K of the misses are limits".

With ``--distractors``, each photo also shows what must get no ID: a fifth light in the middle
of the four, the same size, that is no beacon but an LED sending random data (Manchester
chips of random bits at 10,000 chips/s, about 4.8 rows a chip, as wide as the beacons'
stripes; left out of the map ``locate`` gets), and a camera's date and time burned into the
bottom-right corner.  The run ends with how often ``locate`` detected them and the IDs it gave
them: "IDs given to data lights" and "IDs given to text", which must be 0.

Run: ``python benchmarks/bench_frequency.py [--quick] [--plot out/frequency/errors.png]``
(about ten minutes; ``--quick``, one exposure and one readout, takes a sixth of that;
``--plot`` draws each light's error against the periods it shows; ``--styles``,
``--periods`` and ``--exposures`` measure a part of the sweep with the same seeds, ``--seed
N`` the sweep with seeds from N, ``--worst N`` lists the N worst lights).  A style added to the
sweep later (:data:`LATER_STYLES`) takes the seeds after the others', so theirs stay.
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from camvlp import locate
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.bound import frequency_bounds, frequency_intervals, share_within
from camvlp.sim.render import RenderSettings, render
from camvlp.sim.sensor import camera_date

ROW_TIME_S = 1.0 / 47_540.0
FOCAL_PX = 1000.0
DISTANCE_M = 2.7
FREQS_HZ = (2000.0, 2600.0, 3300.0, 4000.0)
PERIODS = (1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 8.0)
#: light styles: render settings (brightness 1 is the sensor's full scale)
STYLES = {
    "hard": dict(brightness=4.0),  # sharp, saturated stripes
    "hard-dim": dict(brightness=0.8),  # sharp stripes, not saturated
    "soft": dict(brightness=2.0, soft=0.3),
    "core+halo": dict(brightness=4.0, core=4.0, halo=0.4, soft=0.45),
    "off-core": dict(brightness=0.5, core=3.0, core_offset=0.4),  # the core clips, the rim not
}
#: Styles added to the sweep after the first: their photos' seeds come after all the others'.
LATER_STYLES = ("off-core",)
#: The light sending data (--distractors): its frequency in the map (unused: it sends data),
#: and the stamps' date and time.
DATA_HZ = 3000.0
DATA_CHIP_RATE_HZ = 10_000.0
EXPOSURES = (0.05, 0.2, 0.35)  # fractions of the shortest period (4000 Hz)
NOISES = {  # read noise (fraction of full scale), JPEG quality (None: no JPEG)
    "clean": (0.002, None),
    "noisy": (0.02, None),
    "noisy+jpeg80": (0.02, 80),
}
READOUTS = ("rows", "columns-reversed")
_LOCATE_S: list[float] = []  # each photo's locate time, s
#: (seed, light) -> the frequencies its pixels cannot tell from its own (--limits), fractions
_LIMITS: dict[tuple[int, int], np.ndarray] = {}
#: --distractors: data lights and stamps shown, detected, and given an ID
_DISTRACTED = {"data lights": [0, 0, 0], "text": [0, 0, 0]}


def _room(periods: float, style: str, data: bool = False) -> tuple[FixtureMap, Camera]:
    """Four lights each ``periods`` stripe periods across, and a camera that holds them; with
    ``data``, a fifth light in their middle, the size of a 3000 Hz light's, ID 5."""
    diam_px = [periods / (f * ROW_TIME_S) for f in FREQS_HZ]
    reach = 2.6 if STYLES[style].get("halo", 0) > 0 else 1.2  # the glow reaches further
    spacing_px = reach * max(diam_px) + 40.0
    size = int(2 * spacing_px + 40)
    camera = Camera.from_focal(size, size, FOCAL_PX, row_time_s=ROW_TIME_S)
    half = 0.5 * spacing_px * DISTANCE_M / FOCAL_PX
    xz = ((half, half), (-half, half), (-half, -half), (half, -half))
    fixtures = tuple(
        Fixture(
            i + 1,
            np.array([x, -DISTANCE_M, z]),
            d * DISTANCE_M / FOCAL_PX,
            np.array([0.0, 1.0, 0.0]),
            frequency_hz=f,
        )
        for i, ((x, z), d, f) in enumerate(zip(xz, diam_px, FREQS_HZ, strict=True))
    )
    if data:
        d = periods / (DATA_HZ * ROW_TIME_S) * DISTANCE_M / FOCAL_PX
        middle = np.array([0.0, -DISTANCE_M, 0.0])
        fixtures += (Fixture(5, middle, d, np.array([0.0, 1.0, 0.0]), frequency_hz=DATA_HZ),)
    return FixtureMap(fixtures, mode="frequency"), camera


def _measure(
    periods, style, exposure, noise, readout, seed, limits=False, distractors=False
) -> list[tuple[float, ...]]:
    """(periods shown, frequency error %, centre error px, the bound %) per light: NaN errors
    if missed; the bound is the Cramer-Rao bound of the frequency error's standard deviation
    (:func:`camvlp.sim.bound.frequency_bounds`).  With ``distractors``, the photo also shows a
    light sending data and a stamp (not among the rows; counted in ``_DISTRACTED``)."""
    scene, camera = _room(periods, style, data=distractors)
    fmap = FixtureMap(tuple(f for f in scene.fixtures if f.id != 5), mode="frequency")
    read_noise, quality = NOISES[noise]
    extra = {}
    if distractors:
        stamp = camera_date(np.random.default_rng([seed, 8]))
        extra = dict(data_lights=(5,), chip_rate_hz=DATA_CHIP_RATE_HZ, stamp=stamp)
    settings = RenderSettings(
        row_time_s=ROW_TIME_S,
        exposure_s=exposure / max(FREQS_HZ),
        read_noise=read_noise,
        readout=readout,
        seed=seed,
        **STYLES[style],
        **extra,
    )
    pose = Pose.from_euler([0.01, 0.0, -0.02], [90.0, 0.0, 0.0])
    photo = render(camera, scene, pose, settings)
    image, jpeg_error = photo.image, None
    if quality is not None:
        _, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
        image = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        jpeg_error = image.astype(np.float32) - photo.image
    bounds = 100.0 * frequency_bounds(camera, scene, pose, settings, jpeg_error)
    t0 = time.perf_counter()
    res = locate(image, camera, fmap)
    _LOCATE_S.append(time.perf_counter() - t0)
    if distractors:
        _count_distractors(photo, res)
    rows = []
    for t, bound in zip(photo.fixtures, bounds, strict=True):
        if t.sends_data:
            continue
        near = [f for f in res.fixtures if np.hypot(*(f.pixel - t.pixel)) < 0.5 * t.rows_spanned]
        if not near or not np.isfinite(near[0].frequency_hz):
            rows.append((t.frames_spanned, float("nan"), float("nan"), bound))
            continue
        f = near[0]
        true_hz = fmap.get(t.id).frequency_hz
        err = 100.0 * abs(f.frequency_hz / true_hz - 1.0)
        rows.append((t.frames_spanned, err, float(np.hypot(*(f.pixel - t.pixel))), bound))
    if limits and not all(r[1] < 1.0 for r in rows):  # a light off by 1 % or more, or missed
        for i, lo_hi in enumerate(frequency_intervals(camera, scene, pose, settings, jpeg_error)):
            _LIMITS[seed, i] = lo_hi
    return rows


def _count_distractors(photo, res) -> None:
    """Add a photo's data light and stamp to ``_DISTRACTED``: shown, detected (a light
    ``locate`` reports on it), given an ID."""
    data = [t for t in photo.fixtures if t.sends_data]
    for t in data:
        near = [f for f in res.fixtures if np.hypot(*(f.pixel - t.pixel)) < 0.5 * t.rows_spanned]
        _DISTRACTED["data lights"][0] += 1
        _DISTRACTED["data lights"][1] += bool(near)
        _DISTRACTED["data lights"][2] += sum(f.id is not None for f in near)
    if photo.stamp_box is not None:
        on = [f for f in res.fixtures if photo.on_stamp(f.pixel)]
        _DISTRACTED["text"][0] += 1
        _DISTRACTED["text"][1] += bool(on)
        _DISTRACTED["text"][2] += sum(f.id is not None for f in on)


def _line(label: str, rows: list) -> str:
    a = np.array(rows, dtype=float).reshape(-1, 4)
    got = np.isfinite(a[:, 1])
    reach = f"{np.median(a[:, 3]):7.3f} {100.0 * np.nanmean(share_within(a[:, 3] / 100.0)):6.1f}"
    if not got.any():
        return f"{label:<28} {a.shape[0]:5d} {a.shape[0]:5d}   {'':>20}   {'':>13}   {reach}"
    fe, ce = a[got, 1], a[got, 2]
    within = 100.0 * np.mean(got & (a[:, 1] < 1.0))
    return (
        f"{label:<28} {a.shape[0]:5d} {int((~got).sum()):5d}   {np.median(fe):6.2f} "
        f"{fe.max():6.2f} {within:6.1f}   {np.median(ce):6.2f} {ce.max():6.2f}   {reach}"
    )


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one exposure, no readout sweep")
    parser.add_argument("--plot", type=Path, help="save the errors against periods shown (PNG)")
    parser.add_argument("--styles", nargs="+", choices=STYLES, help="only these light styles")
    parser.add_argument("--periods", nargs="+", type=float, help="only these periods shown")
    parser.add_argument("--exposures", nargs="+", type=float, help="only these exposures")
    parser.add_argument(
        "--seed", type=int, default=0, help="first seed of the sweep (0: the documented seeds)"
    )
    parser.add_argument(
        "--worst", type=int, default=0, help="print the N worst lights (their sweep's settings)"
    )
    parser.add_argument(
        "--limits",
        action="store_true",
        help="for each light off by 1 %% or more, the frequencies its pixels cannot tell apart",
    )
    parser.add_argument(
        "--distractors",
        action="store_true",
        help="each photo also shows a light sending data and a burned-in date and time",
    )
    args = parser.parse_args(argv)
    exposures = (0.2,) if args.quick else EXPOSURES
    readouts = READOUTS[:1] if args.quick else READOUTS
    t0 = time.perf_counter()
    by: dict[str, dict] = defaultdict(lambda: defaultdict(list))
    everything = []
    grid = itertools.chain(
        itertools.product(
            PERIODS, [s for s in STYLES if s not in LATER_STYLES], exposures, NOISES, readouts
        ),
        *(itertools.product(PERIODS, [s], exposures, NOISES, readouts) for s in LATER_STYLES),
    )
    worst = []
    for seed, (periods, style, exposure, noise, readout) in enumerate(grid, args.seed):
        if (
            (args.styles and style not in args.styles)
            or (args.periods and not any(abs(periods - p) < 1e-9 for p in args.periods))
            or (args.exposures and not any(abs(exposure - e) < 1e-9 for e in args.exposures))
        ):
            continue  # the same seeds as in the whole sweep
        rows = _measure(
            periods, style, exposure, noise, readout, seed, args.limits, args.distractors
        )
        worst += [
            (r[1], i, (periods, style, exposure, noise, readout, seed), r[3])
            for i, r in enumerate(rows)
        ]
        everything += rows
        by["style, periods"][f"{style:<10} {periods:4.1f}"] += rows
        by["style"][style] += rows
        by["exposure (of a 4000 Hz period)"][f"{exposure:.2f}"] += rows
        by["noise"][noise] += rows
        by["readout"][readout] += rows
    head = f"{'':<28} {'n':>5} {'miss':>5}   {'freq err %':>20}   {'centre px':>13}   {'bound':>14}"
    sub = (
        f"{'':<28} {'':>5} {'':>5}   {'median':>6} {'worst':>6} {'<1 %':>6}   "
        f"{'median':>6} {'worst':>6}   {'sigma %':>7} {'<1 %':>6}"
    )
    for name, groups in by.items():
        print(f"\nby {name}\n{head}\n{sub}")
        for label, rows in groups.items():
            print(_line(label, rows))
    print(f"\n{_line('overall', everything)}")
    a = np.array(everything)
    shown = a[:, 0] >= 1.45  # 1.5 periods, to rounding
    within = shown & (a[:, 1] < 1.0)
    reach = share_within(a[shown, 3] / 100.0)
    finite = shown & np.isfinite(a[:, 3])
    ratio = a[finite, 1] / a[finite, 3]
    print(
        f"lights showing >= 1.5 periods within 1 %: {int(within.sum())} of {int(shown.sum())}"
        f" (the bound expects {np.nansum(reach):.1f}; error / bound: median "
        f"{np.nanmedian(ratio):.1f}, 90th percentile {np.nanpercentile(ratio, 90):.1f}, over "
        f"the {int(finite.sum())} with a finite bound) ({time.perf_counter() - t0:.0f} s)"
    )
    print(
        f"locate per photo of four lights: median {1e3 * np.median(_LOCATE_S):.0f} ms, "
        f"90th percentile {1e3 * np.percentile(_LOCATE_S, 90):.0f} ms"
    )
    if args.distractors:
        (shown, seen, named), (stamps, read, texts) = _DISTRACTED.values()
        print(
            f"distractors: {seen} of {shown} data lights detected, IDs given to data lights "
            f"{named}; stamps with a light detected on them {read} of {stamps}, IDs given to "
            f"text {texts} (both must be 0)"
        )
    for err, i, where, bound in sorted(worst, key=lambda w: -np.nan_to_num(w[0], nan=1e9))[
        : args.worst
    ]:
        lo_hi = _LIMITS.get((where[-1], i))
        told = "" if lo_hi is None else " consistent: {:+.2f} to {:+.2f} %".format(*100 * lo_hi)
        print(f"worst: {err:6.2f} % (bound {bound:.3f} %){told} light {i} of {where}")
    if args.limits:
        _print_limits(worst)
    if args.plot:
        plot(by["style"], args.plot)
        print(f"wrote {args.plot}")


def _print_limits(worst: list) -> None:
    """Each light off by 1 % or more (or missed), whether it is a limit (its pixels are
    consistent with a frequency 1 % off or more), and the summary line "N of M within 1 %, K
    of the misses are limits" over the lights showing 1.5 periods or more."""
    off = [(err, i, where) for err, i, where, _ in worst if not err < 1.0]
    spans = np.array([_LIMITS[where[-1], i] for _, i, where in off]).reshape(-1, 2)
    wide = (spans[:, 0] < -0.01) | (spans[:, 1] > 0.01)
    mid = np.abs(spans.mean(axis=1)) > 0.01
    for (err, i, where), (lo, hi), limit in sorted(
        zip(off, spans, wide, strict=True), key=lambda o: -np.nan_to_num(o[0][0], nan=1e9)
    ):
        kind = "limit" if limit else "not a limit"
        print(
            f"miss: {err:6.2f} % {kind:<11} (its pixels fit {100 * lo:+.2f} to {100 * hi:+.2f} %)"
            f" light {i} of {where}"
        )
    print(
        f"lights off by 1 % or more: {len(off)}; their pixels are consistent (within one "
        f"standard deviation of their noise) with a frequency 1 % off or more for {wide.sum()}"
        f", and the middle of the frequencies they are consistent with is 1 % off or more for "
        f"{mid.sum()}"
    )
    shown = [w for w in worst if w[2][0] >= 1.5 - 1e-9]
    n_within = sum(1 for w in shown if w[0] < 1.0)
    limits = sum(
        1
        for (_, _, where), limit in zip(off, wide, strict=True)
        if where[0] >= 1.5 - 1e-9 and limit
    )
    print(
        f"{n_within} of {len(shown)} within 1 %, {limits} of the {len(shown) - n_within} misses "
        "are limits (lights showing 1.5 periods or more)"
    )


def plot(by_style: dict, path: Path) -> None:
    """Each light's frequency error against the periods it shows, one panel per style, with
    the 1 % line, the share within it per periods shown, and in grey each light's bound (the
    smallest standard deviation any measurement could have)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(by_style), figsize=(3.2 * len(by_style), 3.8), sharey=True)
    rng = np.random.default_rng(0)  # horizontal jitter only, to show the points' density
    for ax, (style, rows) in zip(np.atleast_1d(axes), by_style.items(), strict=True):
        a = np.array(rows, dtype=float).reshape(-1, 4)
        shown = np.round(a[:, 0] * 2) / 2
        err = np.where(np.isfinite(a[:, 1]), a[:, 1], 100.0)  # a miss drawn at the top
        ax.scatter(
            shown * np.exp(rng.uniform(-0.06, 0.06, shown.size)),
            np.maximum(err, 1e-3),
            s=5,
            alpha=0.35,
            color=np.where(err < 1.0, "tab:green", "tab:red"),
        )
        bound = a[:, 3]
        ax.scatter(  # the best any method could do: the bound's standard deviation
            shown * np.exp(rng.uniform(-0.06, 0.06, shown.size)),
            np.clip(bound, 1e-3, 100.0),
            s=14,
            alpha=0.5,
            color="0.35",
            marker="_",
        )
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        for p in np.unique(shown):
            sel = shown == p
            ax.text(p, 40.0, f"{100 * np.mean(err[sel] < 1.0):.0f}", ha="center", fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(PERIODS, [f"{p:g}" for p in PERIODS])
        ax.minorticks_off()
        ax.set_ylim(1e-3, 100)
        ax.set_title(style, fontsize=10)
        ax.set_xlabel("periods shown")
    np.atleast_1d(axes)[0].set_ylabel("frequency error (%)")
    fig.suptitle(
        "dots: each light's error (numbers: % within 1 %);  grey dashes: its bound, the "
        "smallest standard deviation any measurement could have",
        fontsize=9,
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
