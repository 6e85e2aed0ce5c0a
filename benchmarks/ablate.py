"""Ablation of ``locate``'s special paths: what each one gains on the real photos and the
stress grid, and what it costs in time.

Each special path is switched off inside this process by putting the plain behaviour it
falls back to in place of its entry point, where the stage that calls it looks it up
(nothing under ``src/`` changes); the real photographs (``benchmarks/real_photos.py``,
every photo of ``../shared/real``) and the stress grid (``benchmarks/stress_decode.py``,
default looks) are then run as they are run on their own, and compared with the same runs
with nothing switched off, measured the same way in the same process.  The paths
(``--list`` prints them with what each switches off; modules under ``camvlp.pipeline``):

    touching      lit regions are never split into lights (``detect.touching.one_per_light``
                  as ``detect.candidates`` calls it, given a search without its brighter
                  part: one light per region, no power cells; so no light/dark seeds,
                  chords or own faces)
    chords        no lights from clipped chords (``JoinedRegion.chords`` finds none)
    dark-seeds    no lights from the faces in the dark stripes (``JoinedRegion.dark_stripes``
                  finds none resolved)
    codes-differ  two peaks without a neck are never told apart by their stripes' codes
                  (``JoinedRegion.codes_differ`` says no)
    own-face      a light of a joined region is never outlined by its face
                  (``detect.faces.own_face`` as ``detect.refine`` calls it)
    glow-centre   no light centred on its glow (``lamp.glow.centred_on_glow`` as the detect
                  stage, ``pipeline.lights``, calls it: the blobs as detected)
    crowded       lights whose glows joined not fitted jointly (``lamp.crowded.centred_jointly``
                  as ``lamp.glow`` calls it)
    rim           no light moved to or held at its disc's clean rim
                  (``lamp.rim.rim_from_chords``, in ``lamp.glow`` and ``lamp.crowded``)
    radial        no radial fit (``lamp.radial.radial_fit`` fails, in ``lamp.glow`` and
                  ``lamp.crowded``: glowing lights stay as detected, and no joint fit), the
                  rims kept
    glow-decode   no light read again from its separated glow
                  (``decode.glow_split.decode_from_glows`` as ``decode.stage`` calls it)
    light-wave    frequency maps: the plain mean profile per line
                  (``lamp.light_wave.separated_wave`` fails, in ``decode.frequency``)
    freq-centre   frequency maps: a glowing light keeps its detected centre
                  (``decode.frequency._centre``)

Every name patched or probed is public but one: ``decode.frequency._centre`` is the
freq-centre path's entry point (no public function holds that step alone).  The lists of
code that would go (``--list``) name private functions too, only to count their lines.

Several names joined by ``+`` are switched off together in one run.  For each run it prints
the real photos' lights right / wrong / refused and photos located, the stress grid's lamps
decoded / present, wrong IDs, photos located and worst cells, each against the baseline
(the cells and photos that changed), the time of ``locate`` per photo (p50 / p95 / max, and
the share of the baseline's total time the path takes), how many times the switch was hit
and how often the path's own work ran (its probe: 0 when switched off), and the lines of
code that would go with the path.  Run::

    python benchmarks/ablate.py --only real                  # every path, the real photos
    python benchmarks/ablate.py --only real --quick --off freq-centre   # five photos
    python benchmarks/ablate.py --off crowded --off rim       # two paths, both benchmarks
    python benchmarks/ablate.py --only stress --off touching --baseline out/ablate/a.json
    python benchmarks/ablate.py --only stress --phone --off rim    # phone-processed looks
    python benchmarks/ablate.py --check   # every patch and probe found, on one render

The stress grid takes 3 to 8 minutes a run at ``--per-cell 2`` on a quiet machine: run the
paths one after another (``--baseline`` reuses a baseline measured with the same settings).
All the real photos' maps are frequency-coded: the paths of Manchester maps (glow-centre,
crowded, rim, radial, glow-decode, own-face) are not reached there, and the paths of
frequency maps (light-wave, freq-centre) are not reached on the stress grid.  Wall times
on a busy machine are noisy: a path's own time (the seconds spent in its code, measured in
the baseline run itself) is the steadier figure.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import importlib
import inspect
import io
import json
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import real_photos  # (the benchmarks beside this one)
import stress_decode

from camvlp.pipeline import lights
from camvlp.pipeline.decode import frequency, glow_split, stage
from camvlp.pipeline.detect import candidates, refine, touching
from camvlp.pipeline.detect.touching import CandidateSearch, JoinedRegion
from camvlp.pipeline.lamp import crowded, glow, light_wave
from camvlp.pipeline.lamp.radial import RadialFit

REPO = Path(__file__).resolve().parents[1]
#: ``stress_decode.py``'s options of the photos' looks passed on (default looks without).
LOOKS = ("plain", "phone", "distractors")


def _without_high(one_per_light: Callable) -> Callable:
    """A stub maker: ``one_per_light`` given the candidate search without its brighter part
    (``high``), so that it yields every candidate region whole, as one light."""

    def whole_regions(search: CandidateSearch, boxes, several) -> Iterator:
        return one_per_light(dataclasses.replace(search, high=None), boxes, several)

    return whole_regions


def _plain(value: Callable) -> Callable[[Callable], Callable]:
    """A stub maker: the plain function ``value``, whatever the original."""
    return lambda original: value


def _no_chords(region: JoinedRegion) -> np.ndarray:
    """``JoinedRegion.chords`` that finds no light (``[x, y, r]``, shape (0, 3))."""
    return np.empty((0, 3))


def _no_dark_stripes(region: JoinedRegion) -> None:
    """``JoinedRegion.dark_stripes`` that finds the stripes not resolved."""
    return None


def _codes_alike(region: JoinedRegion, a: np.ndarray, b: np.ndarray) -> bool:
    """``JoinedRegion.codes_differ`` that never tells two peaks apart."""
    return False


def _no_face(gray, lit, cell, axis: str, seed) -> None:
    """``own_face`` that finds none."""
    return None


def _as_detected(img, blobs, axis: str, which=None) -> list:
    """``centred_on_glow`` that leaves every blob as detected."""
    return list(blobs)


def _not_jointly(img, blobs, axis: str, glows, rims=None) -> list:
    """``centred_jointly`` that leaves every blob as centred on its own."""
    return blobs


def _no_rim(img, blobs, k: int, axis: str) -> None:
    """``rim_from_chords`` that finds no clean rim."""
    return None


def _no_fit(gray, support, ellipse, axis: str, far: bool = False, **options) -> RadialFit:
    """``radial_fit`` that fails (as it does when it finds no centre)."""
    return RadialFit(np.full(2, np.nan), np.full(2, np.nan), None)


def _not_from_glows(img, blobs, man, fixture_map) -> tuple:
    """``decode_from_glows`` that reads no light again."""
    return man, {}


def _no_wave(gray, support, ellipse, axis: str) -> light_wave.LightWave:
    """``separated_wave`` that fails: ``decode.frequency`` takes the mean profile."""
    nan = float("nan")
    return light_wave.LightWave(nan, nan, nan, (nan, nan), np.full(2, nan), nan, "switched off")


def _detected_centre(blob, support: np.ndarray) -> np.ndarray:
    """``decode.frequency._centre`` that keeps the blob's detected centre."""
    return np.asarray(blob.pixel, dtype=float)


@dataclass(frozen=True)
class Path_:
    """A special path: what switches it off, what tells that its own work ran, and its code.

    ``patches``: (owner, attribute, stub maker taking the attribute's current value), the
    owner the module (or class) where the caller looks the attribute up; ``probe``:
    (owner, attribute) pairs called only when the path does its own work (counted in every
    run before the patches are put in: 0 once the path is off; with ``found``, only the
    calls that return something other than None); ``code``: what would go with it, each
    ``"module"`` (the whole file) or ``"module:name"`` (one function, class or method,
    ``Class.method``), modules under ``camvlp.pipeline``, a leading ``-`` for what stays
    (used elsewhere); ``timed``: the functions whose time is the path's (its patched
    entries when empty: for a switch that only empties an input, the function that input
    would call)."""

    what: str
    patches: tuple
    probe: tuple
    code: tuple[str, ...]
    stress: bool = True  # reached on the stress grid's Manchester maps
    timed: tuple = ()  # what holds its time, (owner, attribute); () its patched entries
    found: bool = False  # the probe counts only its calls that found something


PATHS: dict[str, Path_] = {
    "touching": Path_(
        "every lit region one light: no split into cells (one_per_light without high)",
        ((candidates, "one_per_light", _without_high),),
        ((touching, "light_seeds"),),
        (
            "detect.touching",
            "detect.peaks",
            "-detect.peaks:power_cell",
            "detect.codes",
            "detect.faces",
            "detect.chords",
        ),
    ),
    "chords": Path_(
        "no lights from the chords their clipped lines show (JoinedRegion.chords: none)",
        ((JoinedRegion, "chords", _plain(_no_chords)),),
        ((touching, "chord_seeds"),),
        (
            "detect.chords",
            "detect.touching:JoinedRegion.chords",
            "detect.touching:_with_chords",
        ),
        timed=((touching, "chord_seeds"),),
    ),
    "dark-seeds": Path_(
        "no lights from their faces in the dark stripes (JoinedRegion.dark_stripes: none)",
        ((JoinedRegion, "dark_stripes", _plain(_no_dark_stripes)),),
        ((touching, "dark_seeds"),),
        (
            "detect.faces:dark_seeds",
            "detect.touching:JoinedRegion.dark_stripes",
            "detect.touching:_dark_faces",
        ),
        timed=((touching, "dark_level"), (touching, "dark_seeds")),
    ),
    "codes-differ": Path_(
        "peaks without a neck never told apart by their codes (JoinedRegion.codes_differ)",
        ((JoinedRegion, "codes_differ", _plain(_codes_alike)),),
        ((touching, "codes_differ"),),
        ("detect.codes", "detect.touching:JoinedRegion.codes_differ"),
        timed=((touching, "codes_differ"),),
    ),
    "own-face": Path_(
        "a light of a joined region never outlined by its face in the dark stripes (own_face)",
        ((refine, "own_face", _plain(_no_face)),),
        ((refine, "own_face"),),
        ("detect.faces:own_face",),
    ),
    "glow-centre": Path_(
        "no light centred on its glow in Manchester maps: blobs as detected (centred_on_glow)",
        ((lights, "centred_on_glow", _plain(_as_detected)),),
        ((glow, "glow_levels"),),
        ("lamp.glow", "lamp.crowded", "lamp.rim", "lamp.radial"),
    ),
    "crowded": Path_(
        "lights whose glows joined not fitted jointly (centred_jointly)",
        ((glow, "centred_jointly", _plain(_not_jointly)),),
        ((crowded, "radial_fit"),),
        (
            "lamp.crowded:centred_jointly",
            "lamp.crowded:Fitted",
            "lamp.crowded:_grown",
            "lamp.crowded:_held_by_clipped",
            "lamp.crowded:_refitted",
            "lamp.rim:paste_mask",
            "lamp.radial:radial_model",
        ),
    ),
    "rim": Path_(
        "no light moved to or held at its disc's clean rim (rim_from_chords: none shows)",
        (
            (glow, "rim_from_chords", _plain(_no_rim)),
            (crowded, "rim_from_chords", _plain(_no_rim)),
        ),
        ((glow, "rim_from_chords"), (crowded, "rim_from_chords")),
        (
            "lamp.rim:rim_from_chords",
            "lamp.rim:on_rim",
            "lamp.rim:_edges_beyond",
            "lamp.rim:_trimmed_ellipse",
            "lamp.rim:_consensus",
            "lamp.rim:_ellipse",
            "lamp.glow:_to_clean_rim",
            "lamp.glow:_on_rim",
        ),
        found=True,
    ),
    "radial": Path_(
        "no radial fit: glowing lights stay as detected, no joint fit (radial_fit fails)",
        (
            (glow, "radial_fit", _plain(_no_fit)),
            (crowded, "radial_fit", _plain(_no_fit)),
        ),
        ((glow, "radial_fit"),),
        (
            "lamp.radial",
            "lamp.glow:_centred",
            "lamp.glow:_within_outline",
            "lamp.crowded:centred_jointly",
            "lamp.crowded:_refitted",
            "lamp.crowded:_held_by_clipped",
        ),
    ),
    "glow-decode": Path_(
        "no light read again from its glow separated from its neighbours' (decode_from_glows)",
        ((stage, "decode_from_glows", _plain(_not_from_glows)),),
        ((glow_split, "separated_waveforms"),),
        ("decode.glow_split",),  # (and the 4 lines of decode.stage._manchester that call it)
    ),
    "light-wave": Path_(
        "frequency maps: the plain mean profile per line (separated_wave fails)",
        ((frequency, "separated_wave", _plain(_no_wave)),),
        ((frequency, "separated_wave"),),
        ("lamp.light_wave:separated_wave", "lamp.light_wave:_clip_bounds"),
        stress=False,
    ),
    "freq-centre": Path_(
        "frequency maps: a glowing light keeps its detected centre (frequency._centre)",
        ((frequency, "_centre", _plain(_detected_centre)),),
        ((frequency, "_centre"),),
        ("decode.frequency:_centre",),
        stress=False,
    ),
}


def code_lines(spec: tuple[str, ...]) -> int:
    """Lines of the code a path holds (:attr:`Path_.code`)."""
    total = 0
    for item in spec:
        sign = -1 if item.startswith("-") else 1
        module, _, name = item.lstrip("-").partition(":")
        mod = importlib.import_module(f"camvlp.pipeline.{module}")
        if not name:
            total += sign * len(Path(mod.__file__).read_text().splitlines())
            continue
        obj = inspect.unwrap(functools.reduce(getattr, name.split("."), mod))
        total += sign * len(inspect.getsourcelines(obj)[0])
    return total


class Counter:
    """Calls of the functions it wraps, and the seconds spent in them, by label."""

    def __init__(self) -> None:
        self.calls: dict[str, int] = {}
        self.seconds: dict[str, float] = {}

    def wrap(self, label: str, fn: Callable, found: bool = False) -> Callable:
        """``fn`` counted and timed (a generator's time is that of its iteration); with
        ``found``, only the calls that return something other than None are counted."""
        self.calls.setdefault(label, 0)
        self.seconds.setdefault(label, 0.0)

        def counted(*args, **kwargs):
            self.calls[label] += not found
            t = time.perf_counter()
            out = fn(*args, **kwargs)
            self.seconds[label] += time.perf_counter() - t
            self.calls[label] += found and out is not None
            return self._timed(label, out) if inspect.isgenerator(out) else out

        return counted

    def _timed(self, label: str, gen: Iterator) -> Iterator:
        while True:
            t = time.perf_counter()
            try:
                item = next(gen)
            except StopIteration:
                self.seconds[label] += time.perf_counter() - t
                return
            self.seconds[label] += time.perf_counter() - t
            yield item


@contextlib.contextmanager
def switched_off(names: list[str], counter: Counter, entries: bool = False) -> Iterator[None]:
    """Every path's probe counted (``probe:NAME``: the original, so a probe that a switch
    replaces counts 0), its own code timed (``time:NAME``, :attr:`Path_.timed`), with
    ``entries`` its patched entries' calls counted too (``entry:NAME``), and the named
    paths switched off (their stubs counted as ``hit:NAME``), until the context ends."""
    saved = []

    def put(owner, attr: str, value) -> None:
        saved.append((owner, attr, getattr(owner, attr)))
        setattr(owner, attr, value)

    try:
        for name, p in PATHS.items():  # the originals counted, before any is replaced
            for owner, attr in p.probe:
                put(owner, attr, counter.wrap(f"probe:{name}", getattr(owner, attr), p.found))
            for owner, attr in p.timed or [(o, a) for o, a, _ in p.patches]:
                put(owner, attr, counter.wrap(f"time:{name}", getattr(owner, attr)))
            for owner, attr, _ in p.patches if entries else ():
                put(owner, attr, counter.wrap(f"entry:{name}", getattr(owner, attr)))
        for name in names:
            for owner, attr, make in PATHS[name].patches:
                put(owner, attr, counter.wrap(f"hit:{name}", make(getattr(owner, attr))))
        yield
    finally:
        for owner, attr, value in reversed(saved):
            setattr(owner, attr, value)


@dataclass
class Run:
    """One configuration's results."""

    off: list[str]
    real: dict = field(default_factory=dict)
    stress: dict = field(default_factory=dict)


def run_real(entries: list[dict]) -> dict:
    """Every photo located as a user would (:func:`real_photos.locate_as_user`) and judged."""
    photos = []
    for e in entries:
        result, _, fixture_map = real_photos.locate_as_user(e)
        row = real_photos.judge(e, result, fixture_map)
        photos.append(
            dict(
                photo=f"{e['folder']}/{e['photo']}",
                detected=row.detected,
                right=row.right,
                wrong=row.wrong,
                unchecked=row.unchecked,
                refused=len(row.refused),
                located=row.located,
                error=row.error,
                position=row.position,
                short=row.failures,
                ms=row.timing_ms["total"],
            )
        )
    return dict(photos=photos)


def run_stress(per_cell: int, seed: int, looks: tuple[str, ...] = ()) -> dict:
    """The stress grid as ``stress_decode.py --per-cell N --seed S [looks]`` runs it (its own
    loop and judge; ``looks``: its options such as ``--phone``), its per-cell counts and
    per-photo times read back from its JSON."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "stress.json"
        argv = ["stress_decode.py", "--per-cell", str(per_cell), "--seed", str(seed), *looks]
        saved, sys.argv = sys.argv, [*argv, "--json", str(out)]
        text = io.StringIO()
        try:
            with contextlib.redirect_stdout(text):
                stress_decode.main()
        finally:
            sys.argv = saved
        got = json.loads(out.read_text())
    overall = next((ln for ln in text.getvalue().splitlines() if ln.startswith("overall")), "")
    return dict(
        cells=got["cells"],
        seconds=[s["seconds"] for s in got["seconds"]],
        crashes=got.get("crashes", []),
        overall=overall,
    )


def _times(ms: list[float]) -> str:
    v = np.asarray(ms, dtype=float)
    return f"{np.percentile(v, 50):.0f} / {np.percentile(v, 95):.0f} / {v.max():.0f}"


def _sums(rows: list[dict], keys: tuple[str, ...]) -> dict[str, int]:
    """Each key's total over the rows."""
    return {k: sum(int(r[k]) for r in rows) for k in keys}


def real_summary(real: dict) -> dict:
    """Totals of a real-photo run."""
    p = real["photos"]
    return _sums(p, ("right", "wrong", "unchecked", "refused", "located")) | dict(
        short=sum(bool(r["short"]) for r in p), photos=len(p), ms=[r["ms"] for r in p]
    )


def stress_summary(stress: dict) -> dict:
    """Totals of a stress-grid run."""
    c = stress["cells"]
    rate = sorted(c, key=lambda x: x["decoded"] / max(x["eligible"], 1))
    return _sums(c, ("decoded", "eligible", "wrong", "located", "photos")) | dict(
        worst=[
            f"{x['exposure']:g}/{x['rows_per_chip']:g}: {x['decoded']}/{x['eligible']}"
            for x in rate[:3]
        ],
        ms=[1e3 * s for s in stress["seconds"]],
        crashes=len(stress["crashes"]),
    )


def _count(name: str, s: dict, b: dict, key: str, of: str | None = None) -> str:
    """``name`` and the count ``s[key]`` (out of ``s[of]``), with its change from ``b``'s."""
    whole = f"/{s[of]}" if of else ""
    return f"{name} {s[key]}{whole}" + ("" if s[key] == b[key] else f" ({s[key] - b[key]:+g})")


def _time_lines(what: str, s: dict, b: dict | None) -> list[str]:
    """Locate's time per photo (p50 / p95 / max), and the baseline's when ``b`` is given."""
    out = [f"  {what} locate ms p50 / p95 / max: {_times(s['ms'])}"]
    if b is not None:
        out.append(f"    baseline: {_times(b['ms'])}; {_share(s['ms'], b['ms'])}")
    return out


def real_lines(run: Run, base: Run | None) -> list[str]:
    """A real-photo run's lines: totals (with the change against ``base``), times, and each
    photo whose result changed."""
    s = real_summary(run.real)
    b = real_summary(base.real) if base else s
    counts = [_count(k, s, b, k) for k in ("right", "wrong", "refused")]
    counts += [_count("located", s, b, "located", "photos"), _count("short", s, b, "short")]
    out = ["  real photos: " + ", ".join(counts) + " (short: of their README)"]
    out += _time_lines("real", s, b if base else None)
    if base is None:
        return out
    for new, old in zip(run.real["photos"], base.real["photos"], strict=True):
        keys = ("right", "wrong", "refused", "located", "detected")
        if any(new[k] != old[k] for k in keys) or _moved(new, old):
            was = ", ".join(f"{k} {old[k]}" for k in keys)
            now = ", ".join(f"{k} {new[k]}" for k in keys)
            err = ""
            if _moved(new, old):
                d = _distance(new["position"], old["position"])
                err = f"; error {_err(old)} -> {_err(new)}, moved {d}"
            out.append(f"    changed {new['photo']}: {was} -> {now}{err}")
    return out


def _err(row: dict) -> str:
    return "-" if row["error"] is None else f"{row['error']:.2f}"


def _distance(a, b) -> str:
    if a is None or b is None:
        return "(located / not located)"
    return f"{float(np.linalg.norm(np.subtract(a, b))):.3g} map units"


def _moved(new: dict, old: dict) -> bool:
    """Whether a photo's position changed (by more than 1e-6 map units)."""
    a, b = new["position"], old["position"]
    if (a is None) != (b is None):
        return True
    return a is not None and float(np.max(np.abs(np.subtract(a, b)))) > 1e-6


def _share(ms: list[float], base: list[float]) -> str:
    """The share of the baseline's total locate time the switched-off path took."""
    return f"path's share of the total time {100 * (1 - sum(ms) / sum(base)):+.1f} %"


def stress_lines(run: Run, base: Run | None) -> list[str]:
    """A stress-grid run's lines: totals (with the change against ``base``), worst cells,
    times, and each cell whose counts changed."""
    s = stress_summary(run.stress)
    b = stress_summary(base.stress) if base else s
    counts = [_count("decoded", s, b, "decoded", "eligible"), _count("wrong", s, b, "wrong")]
    counts += [_count("located", s, b, "located", "photos"), _count("crashes", s, b, "crashes")]
    out = [
        "  stress grid: "
        + ", ".join(counts)
        + "; worst cells (exposure/rows per chip): "
        + "; ".join(s["worst"])
    ]
    out += _time_lines("stress", s, b if base else None)
    if base is None:
        return out
    for new, old in zip(run.stress["cells"], base.stress["cells"], strict=True):
        keys = ("decoded", "eligible", "wrong", "located")
        if any(new[k] != old[k] for k in keys):
            out.append(
                f"    changed cell {new['exposure']:g}/{new['rows_per_chip']:g}: "
                + ", ".join(f"{k} {old[k]} -> {new[k]}" for k in keys if new[k] != old[k])
            )
    return out


def _counted(off: list[str], work: Callable[[], dict]) -> dict:
    """``work()`` with the paths ``off`` switched off, and what its counter saw (``calls``:
    switch hits and probes; ``own_s``: each path's own time, seconds)."""
    counter = Counter()
    with switched_off(off, counter):
        got = work()
    seconds = {k[5:]: v for k, v in counter.seconds.items() if k.startswith("time:")}
    calls = {k: v for k, v in counter.calls.items() if not k.startswith("time:")}
    return got | dict(calls=calls, own_s=seconds)


def measure(off: list[str], only: str | None, entries: list[dict], args) -> Run:
    """One configuration run on the benchmarks asked for."""
    run = Run(off)
    if only in (None, "real"):
        run.real = _counted(off, lambda: run_real(entries))
    if only in (None, "stress") and (not off or any(PATHS[n].stress for n in off)):
        looks = tuple(f"--{k}" for k in LOOKS if getattr(args, k))
        run.stress = _counted(off, lambda: run_stress(args.per_cell, args.seed, looks))
    return run


def _own_time(base: dict, name: str, ms: list[float]) -> str:
    """A path's own time in a baseline run (:attr:`Path_.timed`), and its share of the
    total locate time ``ms`` (milliseconds per photo) there."""
    own, total = base["own_s"].get(name, 0.0), 1e-3 * sum(ms)
    return f"    {name}'s own time in the baseline: {own:.1f} s of {total:.0f} s " + (
        f"({100 * own / total:.1f} %)"
    )


def _calls(got: dict) -> list[str]:
    """The switch hits and the probes reached of one benchmark's run."""
    hits = {k[4:]: v for k, v in got["calls"].items() if k.startswith("hit:")}
    probes = {k[6:]: v for k, v in got["calls"].items() if k.startswith("probe:") and v}
    out = ["    switch hit (calls of the stub): " + str(hits)] if hits else []
    return [*out, "    probes reached (calls of each path's own work): " + str(probes)]


def report(run: Run, base: Run | None) -> str:
    """A run's lines: what it switched off, and each benchmark against the baseline's."""
    label = "+".join(run.off) or "baseline (nothing off)"
    lines = [f"== {label}"]
    if run.off:
        what = "; ".join(PATHS[n].what for n in run.off)
        lines.append(f"  switches off: {what}")
        gone = sum(code_lines(PATHS[n].code) for n in run.off)
        lines.append(f"  code that would go: {gone} lines")
    if run.real:
        b = base if base and base.real else None
        lines += real_lines(run, b) + _calls(run.real)
        ms = real_summary(b.real)["ms"] if b else []
        lines += [_own_time(b.real, n, ms) for n in run.off if b]
    if run.stress:
        b = base if base and base.stress else None
        lines += stress_lines(run, b) + _calls(run.stress)
        ms = stress_summary(b.stress)["ms"] if b else []
        lines += [_own_time(b.stress, n, ms) for n in run.off if b]
    elif run.off and not any(PATHS[n].stress for n in run.off):
        lines.append("  stress grid: not run (Manchester maps only: the path is not reached)")
    return "\n".join(lines)


def _saved_baseline(path: Path, settings: dict) -> tuple[Run | None, str]:
    """The baseline run of an earlier ``--json`` measured with the same ``settings`` (its
    ``only`` the same or both benchmarks; a setting it lacks taken as False), or None and
    why not."""
    try:
        saved = json.loads(path.read_text())
        have, first = saved["settings"], saved["runs"][0]
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        return None, f"{path} is no --json of this script ({type(exc).__name__}: {exc})"
    keys = (set(have) | set(settings)) - {"only"}
    same = all(have.get(k, False) == settings.get(k, False) for k in keys)
    if not same or have.get("only") not in (None, settings["only"]) or first["off"]:
        return None, f"{path} was measured with {have}, not {settings}"
    return Run(**first), ""


def _accepts(stub: Callable, original: Callable) -> bool:
    """Whether ``stub`` takes the arguments ``original`` takes: its required positional
    ones by position, the others by name."""
    params = inspect.signature(original).parameters.values()
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    required = [p for p in params if p.kind in kinds and p.default is p.empty]
    variadic = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
    named = {p.name: None for p in params if p.kind not in variadic and p not in required}
    try:
        inspect.signature(stub).bind(*[None] * len(required), **named)
    except TypeError:
        return False
    return True


def _where(owner, attr: str) -> str:
    return f"{getattr(owner, '__module__', '')}.{owner.__name__}.{attr}".lstrip(".")


def check_targets() -> list[str]:
    """What is amiss with the paths' patches, probes, timed functions and code lists: a
    target that is missing, a stub that does not take the original's arguments, a code
    entry that does not resolve (one line each; none when all is well)."""
    problems = []
    for name, p in PATHS.items():
        pairs = [*p.probe, *p.timed, *[(o, a) for o, a, _ in p.patches]]
        problems += [f"{name}: no {_where(o, a)}" for o, a in pairs if not hasattr(o, a)]
        for owner, attr, make in p.patches:
            original = getattr(owner, attr, None)
            if original is not None and not _accepts(make(original), original):
                problems.append(f"{name}: the stub of {_where(owner, attr)} takes other arguments")
        try:
            code_lines(p.code)
        except (AttributeError, ImportError, OSError, TypeError) as exc:
            problems.append(f"{name}: code list {p.code}: {type(exc).__name__}: {exc}")
    return problems


#: The photo ``--check`` locates: a 1080p photo of the stress grid (exposure 0.5 chip, 4 rows
#: per chip, drawn with this seed), its lamps given a glow (halo 0.35, three times as bright).
CHECK_SEED, CHECK_LOOK = 11, dict(halo=0.35, brightness=3.0)


def check() -> int:
    """``--check``: every patch target, probe, timed function and code entry found, every
    stub taking its original's arguments; then one synthetic photo located with nothing
    off, and each path's entry calls and probe calls counted (a path whose probe is not
    reached on it is listed, not an error).  Returns the exit status."""
    problems = check_targets()
    for line in problems:
        print(f"error: {line}", file=sys.stderr)
    if problems:
        return 1
    print(f"every patch target, probe, timed function and code entry of {len(PATHS)} paths found")
    rng = np.random.default_rng(CHECK_SEED)
    drawn = stress_decode.draw_photo(rng, 0.5, 4.0)
    while drawn.big:  # (a 1080p camera)
        drawn = stress_decode.draw_photo(rng, 0.5, 4.0)
    drawn = dataclasses.replace(drawn, settings=dataclasses.replace(drawn.settings, **CHECK_LOOK))
    counter = Counter()
    with switched_off([], counter, entries=True):
        _, result, cond, seconds, _ = stress_decode.shoot(drawn)
    ids = sorted(f.id for f in result.fixtures if f.id is not None)
    print(
        f"one render located ({cond['n']} lamps of the map, halo {cond['halo']}, brightness "
        f"{cond['brightness']}, readout {cond['readout']}; {len(result.fixtures)} lights seen, "
        f"IDs {ids}, located {bool(result)}, {seconds:.1f} s)"
    )
    for name in PATHS:
        entry, probe = counter.calls[f"entry:{name}"], counter.calls[f"probe:{name}"]
        reached = "reached" if probe else "not reached on this photo"
        print(f"  {name:13s} entry calls {entry:3d}, probe calls {probe:3d}: {reached}")
    return 0


def _options() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--off", action="append", help="a path (or paths joined by +) to switch off")
    ap.add_argument("--only", choices=("real", "stress"), help="only this benchmark")
    ap.add_argument("--quick", action="store_true", help="real: only the photos marked quick")
    ap.add_argument("--photos", help="real: only photos whose folder/name contains this text")
    ap.add_argument("--per-cell", type=int, default=2, help="stress photos per grid cell")
    ap.add_argument("--seed", type=int, default=3, help="stress grid seed")
    for look in LOOKS:
        ap.add_argument(f"--{look}", action="store_true", help=f"stress grid: {look} photos")
    ap.add_argument("--json", type=Path, default=REPO / "out" / "ablate" / "ablate.json")
    ap.add_argument("--baseline", type=Path, help="reuse this earlier --json's baseline")
    ap.add_argument("--list", action="store_true", help="list the paths and exit")
    ap.add_argument(
        "--check", action="store_true", help="check every patch and probe on one render, exit"
    )
    return ap.parse_args()


def _real_entries(args: argparse.Namespace) -> list[dict]:
    """The real photos to run: those on disk, of ``--quick`` and ``--photos`` when given."""
    entries = [e for e in real_photos.load_manifest() if e["path"].is_file()]
    if args.quick:
        entries = [e for e in entries if e.get("quick")]
    if args.photos:
        entries = [e for e in entries if args.photos in f"{e['folder']}/{e['photo']}"]
    return entries


def main() -> int:
    args = _options()
    if args.list:
        for name, p in PATHS.items():
            print(f"{name:13s} {code_lines(p.code):5d} lines  {p.what}")
        return 0
    if args.check:
        return check()
    configs = [c.split("+") for c in (args.off or list(PATHS))]
    unknown = sorted({n for c in configs for n in c} - set(PATHS))
    if unknown:
        known = ", ".join(PATHS)
        print(f"error: unknown path {', '.join(unknown)} (known: {known})", file=sys.stderr)
        return 2
    if args.only != "stress" and not real_photos.ROOT.is_dir():
        print(f"error: the real photographs are not at {real_photos.ROOT}", file=sys.stderr)
        return 2
    entries = _real_entries(args)
    if args.only != "stress" and not entries:
        print("error: no real photo matches --quick / --photos", file=sys.stderr)
        return 2
    settings = dict(only=args.only, per_cell=args.per_cell, seed=args.seed)
    settings |= {k: getattr(args, k) for k in LOOKS}
    settings |= {k: getattr(args, k) for k in ("quick", "photos") if getattr(args, k)}
    base = None
    if args.baseline:
        base, why = _saved_baseline(args.baseline, settings)
        if base is None:
            print(f"error: {why}", file=sys.stderr)
            return 2
    if entries:  # warm-up (imports, caches), not measured
        real_photos.locate_as_user(entries[0])
    if base is None:
        t = time.perf_counter()
        base = measure([], args.only, entries, args)
        print(report(base, None), f"\n  ({time.perf_counter() - t:.0f} s)", flush=True)
    runs = [base]
    for off in configs:
        t = time.perf_counter()
        run = measure(off, args.only, entries, args)
        runs.append(run)
        print(report(run, base), f"\n  ({time.perf_counter() - t:.0f} s)", flush=True)
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(dict(settings=settings, runs=[r.__dict__ for r in runs]), indent=1)
        )
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
