"""Stress benchmark of stripe decoding: where does ``camvlp.locate`` read the IDs?

A grid over exposure (0.1 to 1 chip) x rows per chip (2 to 12); in every cell, photos with
random conditions drawn from: LED off level 0 to 10 % of on, brightness 0.5 to 8 times the
sensor's full scale, blur sigma 0.5 to 2 px, JPEG quality 70 to 95, lens distortion (none or
barrel/pincushion), 4 to 16 fixtures, landscape or portrait turned either way (readout rows,
rows-reversed, columns, columns-reversed), 1080p or 20 MP, and lamps plain (half the photos),
with a hot core (in half the photos with a core, off the disc's centre by 0.2 to 0.5 of its
radius), with a halo, or both (drawn apart from the rest: ``--plain`` renders the same photos
with plain discs).  ``--phone`` adds a phone camera's processing, drawn apart as well:
an RGGB mosaic demosaiced, a tone curve (gamma 1.6 to 2.6), sharpening (0 to 1.5),
vignetting (0 to 50 %) and a black point (0 to 0.06 of full scale); ``--tone-given`` gives
``locate`` the camera's tone curve in its camera file (``tone_gamma``), as a calibrated
camera would; ``--tone-gamma G`` gives ``G`` whatever the photo's (e.g. 2.2, sRGB's, for a
phone not calibrated).  The map always holds IDs whose reversed frames are other IDs of the
map (0/14, 2/6, 4/10, 8/12), and the camera file does not say which way the sensor reads:
``locate`` must find the direction itself.  Half the maps give the chip rate
(``chip_rate_hz``), half do not.

Fixtures are discs on a ceiling 2 m above the camera, placed at random without overlap;
each spans 1.0 to 2.6 frames of the code along the readout.  ``--distractors`` adds to every
photo what a decoder must not name: a camera's date and time burned into its bottom-right
corner, and one more disc, placed like the others, that is no beacon but an LED sending random
data (Manchester chips at the photo's chip rate; it is left out of the map ``locate`` gets,
and when the map already holds all 16 IDs, the last disc placed sends data instead).  Both
are drawn apart from the rest, so the photos' other lamps and conditions are those of the run
without it.  A fixture counts as eligible when its whole disc is in the photo, it spans 1.2
frames or more and its disc is clear of the burned-in text (whether ``locate`` detects it or
not); it is decoded when ``locate`` reports its true ID; a wrong ID is any other ID reported
for it.  Decoded fixtures whose stripes fit look-alike IDs almost equally,
the pose telling which (``FixtureResult.look_alikes``), are counted apart too ("told by the
pose").  With ``--distractors``, an ID reported for the data light or for a blob on the
stamp's text is a wrong ID too, and counted apart ("IDs given to data lights", "IDs given to
text").

Prints decode rate and wrong IDs per cell and overall, and saves a plot of the decode rate
over exposure x rows per chip.  Of each lamp detected but not read, it says whether an ideal
decoder of its profile could tell its ID (:func:`separation`, plain discs) and whether the
photo holds it at all (``camvlp.sim.oracle.id_separation``: the renderer's own model, all
else in the photo known, on the plain sensor).  Then ``locate``'s time as a distribution: per
photo size, p50 / p95 / max of the JPEG decode, of each stage and of ``locate`` over the
decode, and the slowest photos with the special paths their time went to
(``LocateResult.paths``; ``benchmarks/timing.py``).  Run::

    python benchmarks/stress_decode.py --per-cell 4 --plot out/stress/decode_map.png

To look at one photo of a run (a miss it reported): ``--photo E R K`` renders and locates only
photo K of the cell of E chips and R rows per chip (the same photo as in the run of the same
``--seed``, ``--per-cell`` and options), prints its conditions, its lamps and what ``locate``
reports of each, and with ``--save DIR`` writes the JPEG, the result drawn on it (the truth's
centres as yellow crosses) and the pictures of each stage::

    python benchmarks/stress_decode.py --seed 29 --phone --photo 0.85 8 0 --save out/photo
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from timing import PhotoTime, path_dict, slowest, time_table  # (the benchmarks beside this one)

from camvlp import Camera, Fixture, FixtureMap, LocateSettings, Pose, RenderSettings, locate, render
from camvlp.pipeline.decode.model_choice import FIXTURE_KNEES, MIN_MARGIN
from camvlp.pipeline.decode.stripe_model import direct_fit, prepared_profile, templates_batch
from camvlp.sim.oracle import id_separation
from camvlp.sim.sensor import camera_date
from camvlp.viz.annotate import annotate, write_debug_pictures

EXPOSURES = (0.1, 0.3, 0.5, 0.7, 0.85, 1.0)
ROWS_PER_CHIP = (2.0, 2.5, 3.0, 4.0, 6.0, 8.0, 12.0)
PAIRS = (0, 14, 2, 6, 4, 10, 8, 12)
ODD = (1, 3, 5, 7, 9, 11, 13, 15)
CEILING_M = 2.0
FRAME_CHIPS = 18


def _eligible(t, photo) -> bool:
    """A lamp counts: its whole disc in the photo, 1.2 frames or more of its code, sending
    its ID (not data), and not under the burned-in text (its disc clear of the stamp)."""
    under = photo.on_stamp(t.pixel, margin_px=0.5 * t.rows_spanned)
    return t.fully_inside and t.frames_spanned >= 1.2 and not t.sends_data and not under


def make_camera(rng: np.random.Generator, big: bool, portrait: bool) -> Camera:
    """1080p (f 1400 px, 15 us rows) or 20 MP (f 3912 px, 10 us rows), maybe distorted."""
    w, h, f, row_time = (5184, 3880, 3912.0, 10e-6) if big else (1920, 1080, 1400.0, 15e-6)
    if portrait:
        w, h = h, w
    k1 = float(rng.choice([0.0, rng.uniform(-0.12, 0.12)]))
    dist = np.array([k1, 0.0, 0.0, 0.0, 0.0]) if k1 else np.zeros(0)
    matrix = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
    return Camera(w, h, matrix, dist, row_time_s=row_time)


def make_scene(rng, camera: Camera, axis: int, rows_per_chip: float, n_wanted: int):
    """Fixtures placed at random, without overlap, on a ceiling the camera faces.

    ``axis`` is the readout's pixel coordinate (1: rows, 0: columns).  Returns the map's
    fixtures (IDs still to assign) as (centre xyz, diameter), and their images as (u, v,
    radius), pixels.
    """
    placed = place_discs(rng, camera, rows_per_chip, n_wanted)
    return [on_ceiling(camera, u, v, r) for u, v, r in placed], placed


def place_discs(
    rng, camera: Camera, rows_per_chip: float, n_wanted: int, placed: list | None = None
) -> list[tuple[float, float, float]]:
    """Discs' images (u, v, radius), pixels, placed at random without overlapping each other
    or those ``placed`` already (kept first in the list), until there are ``n_wanted`` (or 400
    tries); each spans 1.0 to 2.6 frames of the code along the readout."""
    w, h = camera.width, camera.height
    placed = list(placed or [])
    for _ in range(400):
        if len(placed) >= n_wanted:
            break
        frames = rng.uniform(1.0, 2.6)
        d_px = frames * FRAME_CHIPS * rows_per_chip + 2.0  # the disc's extent along the readout
        r = 0.5 * d_px
        margin = r + 6
        if 2 * margin >= min(w, h):
            continue
        u, v = rng.uniform(margin, w - margin), rng.uniform(margin, h - margin)
        if any(np.hypot(u - a, v - b) < r + c + max(40.0, 0.3 * (r + c)) for a, b, c in placed):
            continue
        placed.append((u, v, r))
    return placed


def on_ceiling(camera: Camera, u: float, v: float, r: float) -> tuple[np.ndarray, float]:
    """The disc on the ceiling whose image is centred at (u, v), ``r`` pixels in radius: its
    centre (x, y, z) and diameter, metres."""
    ray = camera.undistort_pixels(np.array([[u, v]]))[0]
    centre = np.array([ray[0], ray[1], 1.0]) * CEILING_M
    return centre, 2 * r * CEILING_M / camera.matrix[0, 0]


def lamp_look(rng: np.random.Generator) -> dict[str, float]:
    """A lamp's look: plain (half the photos), a hot core (1 to 3 times brighter at the
    core's centre; in half the photos with a core, that centre lies 0.2 to 0.5 of the radius
    off the disc's, each lamp its own way), a halo (0.05 to 0.4 of the lamp's level), or
    both.  The core's offset is drawn after the rest, so a photo without it is as before."""
    kind = int(rng.integers(6))
    core = float(rng.uniform(1.0, 3.0)) if kind in (3, 5) else 0.0
    halo = float(rng.uniform(0.05, 0.4)) if kind in (4, 5) else 0.0
    core_offset = 0.0
    if core > 0 and rng.uniform() < 0.5:
        core_offset = float(rng.uniform(0.2, 0.5))
    return dict(core=core, halo=halo, core_offset=core_offset)


def distractors_of(
    rng: np.random.Generator,
    camera: Camera,
    rows_per_chip: float,
    placed: list,
    fixtures: tuple,
) -> tuple[tuple, int, str]:
    """What a decoder must not name, drawn from ``rng``: one more disc placed like the
    others (around the discs' images ``placed``), sending data, with an ID of the frame no
    fixture of ``fixtures`` has (when all 16 are taken, the last disc placed sends data
    instead, as when no room is left for one more), and a camera's date and time to burn in.
    Returns the fixtures to render, the data light's ID and the stamp."""
    ids = {f.id for f in fixtures}
    free = [i for i in range(16) if i not in ids]
    stamp = camera_date(rng)
    more = place_discs(rng, camera, rows_per_chip, len(placed) + 1, placed)[len(placed) :]
    if not free or not more:
        return fixtures, fixtures[-1].id, stamp
    centre, diameter = on_ceiling(camera, *more[0])
    data_id = int(rng.choice(free))
    extra = Fixture(data_id, centre, diameter=diameter, normal=np.array([0.0, 0.0, -1.0]))
    return (*fixtures, extra), data_id, stamp


def phone_look(rng: np.random.Generator) -> dict:
    """A phone camera's processing: an RGGB mosaic demosaiced, a tone curve (gamma 1.6 to
    2.6), unsharp-mask sharpening (0 to 1.5), vignetting (0 to 50 % lost at the corners) and a
    black point (0 to 0.06 of full scale, twice the ambient light: from a lifted background to
    a black one, as phones store it)."""
    return dict(
        bayer=True,
        gamma=float(rng.uniform(1.6, 2.6)),
        sharpen=float(rng.uniform(0.0, 1.5)),
        vignetting=float(rng.uniform(0.0, 0.5)),
        black_point=float(rng.uniform(0.0, 0.06)),
    )


@dataclasses.dataclass(frozen=True)
class Drawn:
    """One photo's conditions as drawn (nothing rendered yet)."""

    camera: Camera
    fmap: FixtureMap
    settings: RenderSettings
    quality: int
    big: bool
    given_rate: bool
    scene: FixtureMap | None = None  # what is rendered, when not ``fmap`` (--distractors)


def draw_photo(
    rng,
    exposure: float,
    rows_per_chip: float,
    looks: bool = True,
    phone: bool = False,
    tone_given: bool = False,
    tone_gamma: float | None = None,
    distractors: bool = False,
) -> Drawn:
    """A photo's random conditions, drawn from ``rng`` (nothing rendered: the render draws
    nothing from ``rng``, so photos can be skipped and the next ones stay the same); the
    lamps' looks, the phone's processing and the distractors are drawn from generators of
    their own, seeded by the photo's render seed."""
    big = rng.uniform() < 0.25
    readout = str(rng.choice(["rows", "rows-reversed", "columns", "columns-reversed"]))
    portrait = readout.startswith("columns")
    camera = make_camera(rng, big, portrait)
    axis = 1 if readout.startswith("rows") else 0
    n_wanted = int(rng.integers(4, 17))
    scene, placed = make_scene(rng, camera, axis, rows_per_chip, n_wanted)
    n = len(scene)
    ids = list(PAIRS[: 2 * min(4, max(2, n // 2))]) + list(rng.permutation(ODD))
    ids = [int(i) for i in rng.permutation(ids[:n])] if n <= len(ids) else ids
    chip_rate = 1.0 / (rows_per_chip * camera.row_time_s)
    fixtures = tuple(
        Fixture(i, c, diameter=d, normal=np.array([0.0, 0.0, -1.0]))
        for i, (c, d) in zip(ids, scene, strict=False)
    )
    given_rate = rng.uniform() < 0.5
    fmap = FixtureMap(fixtures, chip_rate_hz=chip_rate if given_rate else None)
    settings = RenderSettings(
        chip_rate_hz=chip_rate,
        exposure_s=exposure / chip_rate,
        brightness=float(np.exp(rng.uniform(np.log(0.5), np.log(8.0)))),
        off_level=float(rng.uniform(0.0, 0.1)),
        blur_px=float(rng.uniform(0.5, 2.0)),
        readout=readout,
        seed=int(rng.integers(1 << 30)),
    )
    if looks:  # drawn apart, so that every other condition is that of the plain sweep
        settings = dataclasses.replace(settings, **lamp_look(np.random.default_rng(settings.seed)))
    if phone:  # drawn apart too
        settings = dataclasses.replace(
            settings, **phone_look(np.random.default_rng([settings.seed, 7]))
        )
    quality = int(rng.integers(70, 96))
    if tone_given or tone_gamma:  # the camera file says its tone curve, or a guess at it
        camera = dataclasses.replace(camera, tone_gamma=tone_gamma or settings.gamma)
    scene_map = None
    if distractors:  # drawn apart too
        drng = np.random.default_rng([settings.seed, 8])
        shown, data_id, stamp = distractors_of(drng, camera, rows_per_chip, placed, fixtures)
        scene_map = dataclasses.replace(fmap, fixtures=shown)
        fmap = dataclasses.replace(fmap, fixtures=tuple(f for f in shown if f.id != data_id))
        settings = dataclasses.replace(settings, data_lights=(data_id,), stamp=stamp)
    return Drawn(camera, fmap, settings, quality, big, given_rate, scene_map)


def one_photo(rng, exposure: float, rows_per_chip: float, **look):
    """A photo drawn (:func:`draw_photo`, with its keyword arguments ``look``) and taken
    (:func:`shoot`, an exception of ``locate`` caught); returns the render, ``locate``'s
    result (or the exception it raised), the conditions, the time of ``locate`` (s), the map
    ``locate`` was given and the map rendered (with the data light)."""
    d = draw_photo(rng, exposure, rows_per_chip, **look)
    photo, res, cond, dt, _ = shoot(d, catch=True)
    return photo, res, cond, dt, d.fmap, d.scene or d.fmap


def shoot(d: Drawn, catch: bool = False):
    """A drawn photo rendered, stored as a JPEG and located (``keep_stages``); returns the
    render, ``locate``'s result, the conditions (the JPEG's decode time, ms, among them),
    the time of ``locate`` (s) and the JPEG's bytes.  With ``catch``, an exception
    ``locate`` raises is returned as its result."""
    camera, fmap, settings = d.camera, d.fmap, d.settings
    photo = render(camera, d.scene or fmap, Pose(np.eye(3), np.zeros(3)), settings)
    _, buf = cv2.imencode(".jpg", photo.image, [cv2.IMWRITE_JPEG_QUALITY, d.quality])
    t = time.perf_counter()
    image = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    jpeg_ms = 1e3 * (time.perf_counter() - t)
    t = time.perf_counter()
    try:
        res = locate(image, camera, fmap, settings=LocateSettings(keep_stages=True))
    except Exception as exc:  # a crash is a result to report, not the end of the sweep
        if not catch:
            raise
        res = exc
    dt = time.perf_counter() - t
    cond = dict(
        big=d.big,
        readout=str(settings.readout.value),
        n=len(fmap.fixtures),
        quality=d.quality,
        k1=float(camera.distortion[0]) if camera.distortion.size else 0.0,
        brightness=round(settings.brightness, 2),
        off=round(settings.off_level, 3),
        blur=round(settings.blur_px, 2),
        core=round(settings.core, 2),
        core_offset=round(settings.core_offset, 2),
        halo=round(settings.halo, 2),
        chip_rate_given=d.given_rate,
        gamma=round(settings.gamma, 2),
        sharpen=round(settings.sharpen, 2),
        vignetting=round(settings.vignetting, 2),
        black_point=round(settings.black_point, 3),
        jpeg_ms=round(jpeg_ms, 2),  # the JPEG's decode, ms: what locate's time compares with
    )
    return photo, res, cond, dt, buf.tobytes()


def replay(args, look: dict) -> int:
    """``--photo E R K``: the sweep's photo K of cell (E chips, R rows per chip) alone (the
    photos before it drawn, not rendered): its conditions, its lamps, what ``locate``
    reports of each, and with ``--save DIR`` the JPEG, the result drawn on it (the truth's
    centres as yellow crosses) and the pictures of each stage."""
    target = (float(args.photo[0]), float(args.photo[1]), int(args.photo[2]))
    d = drawn_photo(args.seed, args.per_cell, target, **look)
    if d is not None:
        return _report(d, args.save)
    cells = f"exposures {EXPOSURES}, rows per chip {ROWS_PER_CHIP}, photos 0 to {args.per_cell - 1}"
    print(f"error: no photo {target} in the sweep ({cells})", file=sys.stderr)
    return 2


def drawn_photo(seed: int, per_cell: int, target: tuple[float, float, int], **look) -> Drawn | None:
    """Photo ``target`` = (exposure in chips, rows per chip, photo in the cell) of the sweep of
    ``seed`` and ``per_cell`` photos a cell (the photos before it drawn, not rendered), with
    the ``look`` options of :func:`draw_photo`; None when the sweep has no such photo."""
    rng = np.random.default_rng(seed)
    for e in EXPOSURES:
        for r in ROWS_PER_CHIP:
            for k in range(per_cell):
                d = draw_photo(rng, e, r, **look)
                if (e, r, k) == target:
                    return d
    return None


def _report(d: Drawn, save: Path | None) -> int:
    """Print one photo of :func:`replay`, and save its pictures into ``save``."""
    photo, res, cond, dt, jpeg = shoot(d)
    print("conditions", cond)
    print("render settings", d.settings)
    truth = list(photo.fixtures)
    for t in truth:
        eligible = _eligible(t, photo)
        print(
            f"  lamp {t.id:2d} at ({t.pixel[0]:7.1f}, {t.pixel[1]:7.1f}), "
            f"{t.frames_spanned:.2f} frames{'' if eligible else ' (not eligible)'}"
            f"{' (sends data)' if t.sends_data else ''}"
        )
    if photo.stamp_box is not None:
        print(f"  stamp {d.settings.stamp!r} at pixels {photo.stamp_box} (u0, v0, u1, v1)")
    for f in res.fixtures:
        t = min(truth, key=lambda t: float(np.hypot(*(t.pixel - f.pixel))))
        off = float(np.hypot(*(t.pixel - f.pixel)))
        got = "no ID" if f.id is None else f"ID {f.id}"
        how = "used" if f.used else f"not used: {f.reason}"
        print(
            f"  {got} at ({f.pixel[0]:7.1f}, {f.pixel[1]:7.1f}), {off:.1f} px from lamp "
            f"{t.id}; {how}"
        )
    print(f"located: {bool(res)}{'' if res else ', ' + res.reason}; locate took {dt:.2f} s")
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        (save / "photo.jpg").write_bytes(jpeg)
        image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
        drawn = annotate(image, res, d.camera, d.fmap)
        size = max(4, round(max(image.shape[:2]) / 150))
        for t in truth:
            centre = (round(float(t.pixel[0])), round(float(t.pixel[1])))
            cv2.drawMarker(drawn, centre, (0, 255, 255), cv2.MARKER_CROSS, 4 * size, size // 2)
        cv2.imwrite(str(save / "annotated.png"), drawn)
        write_debug_pictures(save / "stages", image, res, res.stages)
        print(f"wrote {save / 'photo.jpg'}, {save / 'annotated.png'} and {save / 'stages'}/")
    return 0


def separation(
    profile, weights, true_id: int, fmap: FixtureMap, rpc: float, exposure: float, blur: float
):
    """How well an ideal decoder that knows the photo's true chip length, exposure and blur
    could tell the true ID from the map's others on this profile.

    The true ID's model (its knee and phase fitted) is fitted to the profile; every other ID's
    model (knee and phase free) is then fitted to that noise-free curve.  Returns the smallest
    expected decimal log likelihood ratio (its residual over twice the profile's noise variance,
    inflated for correlated residuals as the decoder does) and the ID it belongs to: below
    ``MIN_MARGIN``, no decoder may name the ID at that safety, whatever its parameters.
    """
    s = 32
    ids = sorted(f.id for f in fmap.fixtures)
    book = fmap.frame.codebook[ids]
    kn = np.asarray(FIXTURE_KNEES)
    one = np.ones(kn.size)
    t = templates_batch(book, rpc, one * exposure, kn, one, one * blur, s)  # (K, I, P)
    p, w = prepared_profile(profile, weights)
    x = np.arange(p.size) / rpc * s
    phases = np.arange(t.shape[2], dtype=float)

    def best_fit(target, k):
        fits = [direct_fit(target, w, t[v, k], x, phases) for v in range(kn.size)]
        v = int(np.argmin([f[0].min() for f in fits]))
        j = int(np.argmin(fits[v][0]))
        return fits[v][0][j], fits[v][1][j], fits[v][2][j], v, j

    it = ids.index(true_id)
    rss, g, o, v, j = best_fit(p, it)
    xs = (x + j) % t.shape[2]
    ideal = g * np.interp(xs, np.arange(t.shape[2] + 1), np.append(t[v, it], t[v, it][0])) + o
    r = ((p - ideal) * np.sqrt(w))[w > 0]  # alike in variance, as the decoder takes them
    rho = float(np.clip(np.dot(r[1:], r[:-1]) / max(np.dot(r, r), 1e-300), 0.0, 0.95))
    var = max(rss / max(r.size - 4, 1), 1e-12) * (1 + rho) / (1 - rho)
    seps = [
        (best_fit(ideal, k)[0] / (2 * var) / np.log(10), ids[k]) for k in range(len(ids)) if k != it
    ]
    return min(seps)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--per-cell", type=int, default=4, help="photos per grid cell")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--plot", type=Path, help="save the decode-rate map here (PNG)")
    ap.add_argument("--json", type=Path, help="write per-fixture results here")
    ap.add_argument(
        "--plain", action="store_true", help="plain discs only (no hot cores, no halos)"
    )
    ap.add_argument(
        "--phone",
        action="store_true",
        help="a phone camera's processing too (Bayer mosaic, tone curve, sharpening, vignetting)",
    )
    ap.add_argument(
        "--tone-given",
        action="store_true",
        help="with --phone: the camera file gives the camera's tone curve (tone_gamma)",
    )
    ap.add_argument(
        "--tone-gamma",
        type=float,
        metavar="G",
        help="with --phone: the camera file gives tone_gamma G, whatever the photo's",
    )
    ap.add_argument(
        "--photo",
        nargs=3,
        metavar=("E", "R", "K"),
        help="only photo K of the cell of E chips and R rows per chip (see --save)",
    )
    ap.add_argument("--save", type=Path, help="with --photo: save its pictures in this folder")
    ap.add_argument(
        "--distractors",
        action="store_true",
        help="every photo also shows a light sending data and a burned-in date and time",
    )
    args = ap.parse_args()
    look = dict(
        looks=not args.plain,
        phone=args.phone,
        tone_given=args.tone_given,
        tone_gamma=args.tone_gamma,
        distractors=args.distractors,
    )
    if args.photo:
        return replay(args, look)
    rng = np.random.default_rng(args.seed)
    cells = {}
    records = []
    per_photo = []  # (seconds, cell, photo in the cell, lamps, conditions): the JSON's
    photo_times: list[PhotoTime] = []  # each located photo's times per stage and special path
    oracles = []  # (decimal log likelihood ratio, closest ID) of the lamps read wrongly or not
    crashes = []  # (exposure, rows per chip, photo in the cell, the exception) where locate raised
    t0 = time.perf_counter()
    n_cells = len(EXPOSURES) * len(ROWS_PER_CHIP)
    for ci, (exposure, rpc) in enumerate((e, r) for e in EXPOSURES for r in ROWS_PER_CHIP):
        eligible = decoded = told = wrong = located = ambiguous = to_data = to_text = 0
        times = []
        for i_photo in range(args.per_cell):
            photo, res, cond, dt, fmap, scene = one_photo(rng, exposure, rpc, **look)
            times.append(dt)
            truth = [t for t in photo.fixtures]
            eligible_k = {k for k, t in enumerate(truth) if _eligible(t, photo)}
            eligible += len(eligible_k)
            if isinstance(res, Exception):  # every lamp missed; listed at the end
                crashes.append((exposure, rpc, i_photo, f"{type(res).__name__}: {res}"))
                per_photo.append((dt, exposure, rpc, i_photo, 0, cond))
                missed = sorted(truth[k].id for k in eligible_k)
                records.append(  # one record for the photo's lamps
                    dict(exposure=exposure, rows_per_chip=rpc, ids=missed, got=None)
                    | dict(reason=f"locate raised {type(res).__name__}", **cond)
                )
                continue
            per_photo.append((dt, exposure, rpc, i_photo, len(res.fixtures), cond))
            h, w = photo.image.shape[:2]
            looks = {k: cond[k] for k in ("n", "brightness", "core", "halo", "gamma")}
            photo_times.append(
                PhotoTime(
                    f"exposure {exposure:g} chip, {rpc:g} rows per chip, photo {i_photo}, "
                    f"{len(res.fixtures)} lights, {looks}",
                    f"{w}x{h}",
                    cond["jpeg_ms"],
                    res.timing_ms,
                    path_dict(res.paths),
                )
            )
            located += bool(res)
            reported: set[int] = set()
            for k_fr, fr in enumerate(res.fixtures):
                d = [np.hypot(*(t.pixel - fr.pixel)) for t in truth]
                k = int(np.argmin(d))
                t = truth[k]
                if d[k] > 0.25 * t.rows_spanned + 3 or t.sends_data:
                    what = "data light" if d[k] <= 0.25 * t.rows_spanned + 3 else None
                    if what is None and photo.on_stamp(fr.pixel):
                        what = "text"
                    if what is None or fr.id is None:
                        continue  # refused, or not one of the discs (should not happen)
                    wrong += 1
                    to_data += what == "data light"
                    to_text += what == "text"
                    records.append(
                        dict(exposure=exposure, rows_per_chip=rpc, id=None, got=fr.id, on=what)
                        | dict(pixel=[round(float(x), 1) for x in fr.pixel], **cond)
                    )
                    continue
                elig = k in eligible_k and k not in reported  # (a disc reported twice: once)
                reported.add(k)
                ok = fr.id == t.id
                bad = fr.id is not None and fr.id != t.id
                decoded += elig and ok
                told += elig and ok and bool(fr.look_alikes)
                wrong += bad
                sep = oracle = None
                if elig and not ok and res.stages is not None:
                    prof = res.stages.profiles[k_fr]
                    wts = res.stages.profile_weights[k_fr]
                    if str(res.readout).endswith("reversed") != cond["readout"].endswith(
                        "reversed"
                    ):
                        prof, wts = prof[::-1], wts[::-1]  # the true sensor order
                    sep = separation(prof, wts, t.id, fmap, rpc, exposure, cond["blur"])
                    ambiguous += int(sep[0] < MIN_MARGIN)
                    oracle = id_separation(photo, scene, k)
                    if oracle is not None:
                        oracles.append((float(oracle[0]), int(oracle[1])))
                if (elig and not ok) or bad:
                    records.append(
                        dict(
                            exposure=exposure,
                            rows_per_chip=rpc,
                            id=t.id,
                            got=fr.id,
                            frames=round(t.frames_spanned, 2),
                            margin=round(fr.margin, 2),
                            reason=fr.reason,
                            separation=None if sep is None else round(float(sep[0]), 2),
                            closest_id=None if sep is None else int(sep[1]),
                            oracle=None if oracle is None else round(float(oracle[0]), 1),
                            oracle_closest_id=None if oracle is None else int(oracle[1]),
                            photo_readout=str(res.readout),
                            fitted_rpc=round(res.rows_per_chip, 3),
                            fitted_exposure=round(res.exposure_chips, 3),
                            **cond,
                        )
                    )
            for k in sorted(eligible_k - reported):  # a disc no blob stands for: a miss
                t = truth[k]
                records.append(
                    dict(
                        exposure=exposure,
                        rows_per_chip=rpc,
                        id=t.id,
                        got=None,
                        frames=round(t.frames_spanned, 2),
                        reason="not detected",
                        **cond,
                    )
                )
        cells[(exposure, rpc)] = dict(
            eligible=eligible,
            decoded=decoded,
            told=told,
            wrong=wrong,
            located=located,
            ambiguous=ambiguous,
            photos=args.per_cell,
            locate_ms=1e3 * float(np.median(times)),
        )
        if args.distractors:
            cells[(exposure, rpc)] |= dict(ids_to_data=to_data, ids_to_text=to_text)
        print(
            f"\r{ci + 1}/{n_cells} cells  {time.perf_counter() - t0:.0f} s",
            end="",
            file=sys.stderr,
            flush=True,
        )
    print(file=sys.stderr)
    apart = " IDs given to data lights | IDs given to text |" if args.distractors else ""
    print(
        "| exposure (chips) | rows per chip | fixtures >= 1.2 frames | decoded | told by the pose "
        "| wrong IDs | photos located | not identifiable | decoded of the identifiable |" + apart
    )
    print("|---|---|---|---|---|---|---|---|---|" + "---|---|" * bool(apart))
    for (e, r), c in cells.items():
        rate = 100 * c["decoded"] / max(c["eligible"], 1)
        ident = c["eligible"] - c["ambiguous"]
        print(
            f"| {e:g} | {r:g} | {c['eligible']} | {c['decoded']} ({rate:.1f} %) | {c['told']} | "
            f"{c['wrong']} | "
            f"{c['located']} / {c['photos']} | {c['ambiguous']} | "
            f"{c['decoded']} / {ident} ({100 * c['decoded'] / max(ident, 1):.1f} %) |"
            + (f" {c['ids_to_data']} | {c['ids_to_text']} |" if apart else "")
        )
    tot = {
        k: sum(c.get(k, 0) for c in cells.values())
        for k in ("eligible", "decoded", "told", "wrong", "ambiguous", "ids_to_data", "ids_to_text")
    }
    photos = sum(c["photos"] for c in cells.values())
    located = sum(c["located"] for c in cells.values())
    worst = min(cells.items(), key=lambda kv: kv[1]["decoded"] / max(kv[1]["eligible"], 1))
    worst_id = min(
        cells.items(),
        key=lambda kv: kv[1]["decoded"] / max(kv[1]["eligible"] - kv[1]["ambiguous"], 1),
    )
    ident = tot["eligible"] - tot["ambiguous"]
    print(
        f"\noverall: {tot['decoded']} / {tot['eligible']} fixtures spanning >= 1.2 frames decoded "
        f"({100 * tot['decoded'] / max(tot['eligible'], 1):.2f} %; {tot['told']} of them "
        f"look-alikes told by the pose, so {tot['decoded'] - tot['told']} from the stripes alone), "
        f"wrong IDs {tot['wrong']}"
        + (
            f" ({tot['ids_to_data']} given to data lights, {tot['ids_to_text']} to text)"
            if args.distractors
            else ""
        )
        + f", photos located {located} / {photos}; worst cell exposure {worst[0][0]:g} chip, "
        f"{worst[0][1]:g} rows per chip: {worst[1]['decoded']} / {worst[1]['eligible']}; "
        f"{time.perf_counter() - t0:.0f} s"
    )
    print(
        f"not identifiable from their stripes (even with the true chip length, exposure and "
        f"blur, another ID of the map fits within a margin of {MIN_MARGIN:g}, and the pose did "
        f"not tell them apart; the ideal decoder models plain discs, so for lamps with a hot "
        f"core or a halo this is an upper count): "
        f"{tot['ambiguous']}; decoded of the identifiable: {tot['decoded']} / {ident} "
        f"({100 * tot['decoded'] / max(ident, 1):.2f} %), worst cell exposure "
        f"{worst_id[0][0]:g} chip, {worst_id[0][1]:g} rows per chip: {worst_id[1]['decoded']} / "
        f"{worst_id[1]['eligible'] - worst_id[1]['ambiguous']}"
    )
    if oracles:
        told_apart = sum(v >= MIN_MARGIN for v, _ in oracles)
        print(
            f"of the {len(oracles)} eligible lamps detected but not read on the plain sensor, "
            f"the renderer's own model (all else in the photo known: their halos and their "
            f"neighbours' glows) tells {told_apart} from every other ID at a margin of "
            f"{MIN_MARGIN:g} or more (smallest margins: "
            f"{', '.join(f'{v:.3g} to ID {i}' for v, i in sorted(oracles)[:5])})"
        )
    if crashes:
        print(f"locate raised on {len(crashes)} photos (counted not located, every lamp missed):")
        for e, r, i, what in crashes:
            print(f"   exposure {e:g}, {r:g} rows per chip, photo {i}: {what}")
    for r in records[:40]:
        print("  ", r)
    print(time_table(photo_times))
    print(slowest(photo_times))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                dict(
                    cells=[dict(exposure=e, rows_per_chip=r, **c) for (e, r), c in cells.items()],
                    misses=records,
                    seconds=[
                        dict(seconds=round(dt, 3), exposure=e, rows_per_chip=r, photo=i, lights=n)
                        for dt, e, r, i, n, _ in per_photo
                    ],
                    times=[dataclasses.asdict(t) for t in photo_times],
                )
                | (
                    dict(
                        crashes=[
                            dict(exposure=e, rows_per_chip=r, photo=i, error=what)
                            for e, r, i, what in crashes
                        ]
                    )
                    if crashes
                    else {}
                ),
                indent=1,
            )
        )
    if args.plot:
        plot(cells, args.plot)
        print(f"wrote {args.plot}")
    return 0


def plot(cells, path: Path) -> None:
    """Decode rate over exposure x rows per chip, of all fixtures and of those identifiable
    from their stripes, with counts and wrong IDs in each cell."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True)
    fig.subplots_adjust(left=0.07, right=0.88, wspace=0.08, top=0.86)
    for ax, of_ident in zip(axes, (False, True), strict=True):
        rate = np.full((len(EXPOSURES), len(ROWS_PER_CHIP)), np.nan)
        for i, e in enumerate(EXPOSURES):
            for j, r in enumerate(ROWS_PER_CHIP):
                c = cells.get((e, r))
                if not c:
                    continue
                n = c["eligible"] - (c["ambiguous"] if of_ident else 0)
                if n:
                    rate[i, j] = 100 * c["decoded"] / n
                text = f"{c['decoded']}/{n}"
                if c["wrong"]:
                    text += f"\n{c['wrong']} wrong"
                ax.text(j, i, text, ha="center", va="center", fontsize=8)
        im = ax.imshow(rate, origin="lower", cmap="RdYlGn", vmin=80, vmax=100, aspect="auto")
        ax.set_xticks(range(len(ROWS_PER_CHIP)), [f"{r:g}" for r in ROWS_PER_CHIP])
        ax.set_yticks(range(len(EXPOSURES)), [f"{e:g}" for e in EXPOSURES])
        ax.set_xlabel("rows per chip")
        ax.set_title(
            "decoded / identifiable from their stripes\n(by an ideal plain-disc decoder)"
            if of_ident
            else "decoded / fixtures spanning >= 1.2 frames\n(all conditions drawn in the cell)",
            fontsize=10,
        )
    axes[0].set_ylabel("exposure (chips)")
    fig.colorbar(im, ax=axes, label="decoded (%)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
