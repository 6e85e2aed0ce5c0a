"""Running the tracker over a video: the files it writes, and its figures against the truth.

:func:`run_track` feeds the frames of a :class:`camvlp.io.video.FrameSource` to a
:class:`camvlp.pipeline.track.Tracker` and writes, as it goes, into a folder (``camvlp track``
gives it a temporary one and moves the files into place once every output is written, so a
failure leaves nothing; a run that the input's end or an interruption stops early is whole):

* ``trajectory.csv``: one row per frame, ``frame,t,x,y,z,theta_x,theta_y,theta_z,
  fixtures_used,reprojection_rms_px,status`` (filtered pose; ``fixtures_used`` the IDs,
  space-separated), then ``x_raw,y_raw,z_raw,theta_x_raw,theta_y_raw,theta_z_raw`` (the
  frame's own solve) and ``reason``;
* ``fixtures.csv``: one row per blob per frame, ``frame,id,u,v,source,used,reason``.

:func:`summarize` gives the figures of ``summary.json``, with the errors when the input has
its truth beside it (see :mod:`camvlp.sim.video`), read before the run by :func:`read_truths`.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.textfiles import read_text_file
from camvlp.io.video import FrameSource, read_truth
from camvlp.pipeline.track.tracker import STATUSES, Tracker, TrackFrame

__all__ = [
    "LOCATED",
    "TRAJECTORY_CSV_COLUMNS",
    "TrackRun",
    "Truths",
    "not_located_reasons",
    "read_truths",
    "run_track",
    "summarize",
]

#: Columns of ``trajectory.csv``.
TRAJECTORY_CSV_COLUMNS = (
    "frame",
    "t",
    "x",
    "y",
    "z",
    "theta_x",
    "theta_y",
    "theta_z",
    "fixtures_used",
    "reprojection_rms_px",
    "status",
    "x_raw",
    "y_raw",
    "z_raw",
    "theta_x_raw",
    "theta_y_raw",
    "theta_z_raw",
    "reason",
)


@dataclass
class TrackRun:
    """What a run produced.

    Attributes
    ----------
    names : list of str
        Each frame's name (number in a video, file name in a folder).
    frames : list of TrackFrame
        The tracker's answers, one per frame (``lost`` for unreadable ones).
    seconds : float
        Wall time of the run, reading included, s.
    read_seconds : float
        Of which reading and decoding the frames, s.
    warnings : list of str
        What the source skipped, where it broke off, or the interruption.
    """

    names: list[str] = field(default_factory=list)
    frames: list[TrackFrame] = field(default_factory=list)
    seconds: float = 0.0
    read_seconds: float = 0.0
    warnings: list[str] = field(default_factory=list)


def _fmt(v, nd: int) -> str:
    return "" if v is None or not np.isfinite(v) else f"{float(v):.{nd}f}"


def _row(name: str, f: TrackFrame) -> list[str]:
    pos = f.position if f.position is not None else [None] * 3
    eul = f.euler_deg if f.euler_deg is not None else [None] * 3
    raw = f.raw_position if f.raw_position is not None else [None] * 3
    raw_e = f.raw_euler_deg if f.raw_euler_deg is not None else [None] * 3
    return [
        name,
        _fmt(f.t, 6),
        *(_fmt(v, 6) for v in pos),
        *(_fmt(v, 4) for v in eul),
        " ".join(str(i) for i in f.fixtures_used),
        _fmt(f.reprojection_rms_px, 3),
        f.status,
        *(_fmt(v, 6) for v in raw),
        *(_fmt(v, 4) for v in raw_e),
        f.reason,
    ]


def run_track(
    source: FrameSource,
    tracker: Tracker,
    out_dir: str | Path,
    *,
    progress: Callable[[int], None] | None = None,
) -> TrackRun:
    """Track every frame of ``source`` and write ``trajectory.csv`` and ``fixtures.csv``.

    A frame that cannot be read, or that is not of the camera's size, gets a ``lost`` row
    with the reason and the run goes on; an interruption (Ctrl-C) ends it with the rows so
    far written and a warning.

    Parameters
    ----------
    source : FrameSource
        The frames (see :func:`camvlp.io.video.open_frames`).
    tracker : Tracker
        A fresh tracker for the video's camera and room.
    out_dir : str or Path
        Where to write (created when missing).
    progress : callable, optional
        Called with the number of frames done after each frame.

    Returns
    -------
    TrackRun
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        traj_fh = (out / "trajectory.csv").open("w", newline="")
        fix_fh = (out / "fixtures.csv").open("w", newline="")
    except OSError as exc:
        raise InputError(f"cannot write the output: {exc.strerror or exc}", out) from None
    run = TrackRun()
    start = time.perf_counter()
    with traj_fh, fix_fh:
        tw, fw = csv.writer(traj_fh), csv.writer(fix_fh)
        tw.writerow(TRAJECTORY_CSV_COLUMNS)
        fw.writerow(("frame", "id", "u", "v", "source", "used", "reason"))
        frames = iter(source)
        try:
            while True:
                r0 = time.perf_counter()
                frame = next(frames, None)
                run.read_seconds += time.perf_counter() - r0
                if frame is None:
                    break
                index = len(run.frames)
                if frame.image is None:
                    result = TrackFrame.lost(index, frame.t, frame.error)
                elif not math.isfinite(frame.t):
                    result = TrackFrame.lost(index, frame.t, "the frame has no time")
                else:
                    try:
                        result = tracker.update(frame.image, frame.t)
                    except InputError as exc:
                        result = TrackFrame.lost(index, frame.t, exc.what)
                run.names.append(frame.name)
                run.frames.append(result)
                tw.writerow(_row(frame.name, result))
                for b in result.fixtures:
                    fw.writerow(
                        (
                            frame.name,
                            "" if b.id is None else b.id,
                            f"{b.pixel[0]:.2f}",
                            f"{b.pixel[1]:.2f}",
                            b.source,
                            int(b.used),
                            b.reason,
                        )
                    )
                if progress is not None:
                    progress(len(run.frames))
        except KeyboardInterrupt:
            run.warnings.append(f"interrupted after {len(run.frames)} frames")
    run.seconds = time.perf_counter() - start
    run.warnings[:0] = list(source.warnings)
    return run


#: A frame's fixtures in the truth: ``(id, u, v, fully_inside)`` per fixture, by frame name.
FixturesTruth = dict[str, list[tuple[int, float, float, bool]]]


@dataclass(frozen=True)
class Truths:
    """The truth beside an input (what ``camvlp render-video`` writes), read before the run.

    Attributes
    ----------
    poses : dict or None
        Frame name -> ``(x, y, z, theta_x, theta_y, theta_z)`` (map units, degrees).
    fixtures : dict or None
        Frame name -> ``(id, u, v, fully_inside)`` of each fixture (pixels).
    """

    poses: dict[str, np.ndarray] | None = None
    fixtures: FixturesTruth | None = None


def read_truths(source: FrameSource) -> Truths:
    """The truth files found beside ``source`` (none when there are none).

    Raises
    ------
    InputError
        A truth file that cannot be read, naming it (before any frame is processed).
    """
    poses = read_truth(source.truth_path) if source.truth_path is not None else None
    fixtures = None
    if source.fixtures_truth_path is not None:
        fixtures = _read_fixture_truth(source.fixtures_truth_path)
    return Truths(poses, fixtures)


def _read_fixture_truth(path: Path) -> FixturesTruth:
    out: FixturesTruth = {}
    text = read_text_file(path, "fixtures' truth")
    try:
        for r in csv.DictReader(io.StringIO(text, newline="")):
            out.setdefault(str(r["frame"]).strip(), []).append(
                (int(r["id"]), float(r["u"]), float(r["v"]), r["fully_inside"] == "1")
            )
    except (KeyError, TypeError, ValueError):
        raise InputError("cannot read the fixtures' truth", path) from None
    return out


def summarize(run: TrackRun, truths: Truths | None = None) -> dict:
    """The figures of ``summary.json``.

    Keys: ``frames``, one count per status (``fix``, ``tracked``, ``predicted``, ``lost``),
    ``fix_rate`` and ``fix_or_tracked_rate`` (fractions of the frames), ``frames_per_second``
    (reading included), ``reading_share``, ``warnings``, ``not_located`` (why the frames that
    were neither a fix nor tracked were not located: ``{"reason", "frames"}`` per reason,
    the most frequent first, a tie in the order met); with the truth, ``errors``:
    ``position_rmse`` (filtered, over frames with a position), ``raw_position_rmse`` (the
    frames' own solves), ``position_max``, ``angle_rmse_deg`` (map units, degrees), per status;
    with the fixtures' truth, ``wrong_ids`` (blobs given an ID whose nearest true fixture
    has another), ``used_not_fully_inside`` (fixtures a pose used while their disc was not
    wholly in the picture: cut or gone) and ``pickup_frames`` (per fixture entering the
    picture: frames from when its whole disc is inside to its first use).
    """
    frames = run.frames
    n = len(frames)
    counts = {s: sum(f.status == s for f in frames) for s in STATUSES}
    out: dict = {
        "frames": n,
        **counts,
        "fix_rate": counts["fix"] / n if n else 0.0,
        "fix_or_tracked_rate": (counts["fix"] + counts["tracked"]) / n if n else 0.0,
        "frames_per_second": n / run.seconds if run.seconds > 0 else None,
        "reading_share": run.read_seconds / run.seconds if run.seconds > 0 else None,
        "warnings": list(run.warnings),
        "not_located": not_located_reasons(frames),
    }
    truths = truths or Truths()
    if truths.poses is not None:
        out["errors"] = _errors(run, truths.poses)
    if truths.fixtures is not None:
        out.update(_id_checks(run, truths.fixtures))
    return out


#: The statuses of a located frame (its own fix, or tracked from its fixtures).
LOCATED = ("fix", "tracked")


def not_located_reasons(frames: list[TrackFrame]) -> list[dict]:
    """Why the frames that were not located (neither ``fix`` nor ``tracked``) were not:
    ``[{"reason": text, "frames": count}, ...]``, the most frequent reason first (a tie in
    the order the reasons were met); a frame without a reason counts as "no reason given"."""
    counts = Counter(f.reason or "no reason given" for f in frames if f.status not in LOCATED)
    return [{"reason": reason, "frames": n} for reason, n in counts.most_common()]


def _rmse(e: np.ndarray) -> float | None:
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e**2))) if e.size else None


def _errors(run: TrackRun, truth: dict[str, np.ndarray]) -> dict:
    pos_err, raw_err, ang_err, status = [], [], [], []
    for name, f in zip(run.names, run.frames, strict=True):
        tv = truth.get(name)
        if tv is None:
            continue
        status.append(f.status)
        pos_err.append(np.linalg.norm(f.position - tv[:3]) if f.position is not None else math.nan)
        raw_err.append(
            np.linalg.norm(f.raw_position - tv[:3]) if f.raw_position is not None else math.nan
        )
        if f.euler_deg is not None:
            d = (f.euler_deg - tv[3:] + 180.0) % 360.0 - 180.0
            ang_err.append(float(np.linalg.norm(d)))
        else:
            ang_err.append(math.nan)
    pe, re_, ae, st = np.array(pos_err), np.array(raw_err), np.array(ang_err), np.array(status)
    per_status = {
        s: {"frames": int((st == s).sum()), "position_rmse": _rmse(pe[st == s])}
        for s in STATUSES[:3]
    }
    return {
        "frames_with_truth": len(status),
        "position_rmse": _rmse(pe),
        "position_max": float(np.nanmax(pe)) if np.any(np.isfinite(pe)) else None,
        "raw_position_rmse": _rmse(re_),
        "angle_rmse_deg": _rmse(ae),
        "by_status": per_status,
    }


def _id_checks(run: TrackRun, ft: FixturesTruth) -> dict:
    wrong = 0
    checked = 0
    used_outside = 0
    used_by_frame: list[set[int]] = []
    for name, f in zip(run.names, run.frames, strict=True):
        used = {b.id for b in f.fixtures if b.used and b.id is not None}
        used_by_frame.append(used)
        truths = ft.get(name, [])
        if not truths:
            continue
        used_outside += len(used - {t[0] for t in truths if t[3]})
        tid = np.array([t[0] for t in truths])
        tpx = np.array([[t[1], t[2]] for t in truths])
        for b in f.fixtures:
            if b.id is None:
                continue
            d = np.linalg.norm(np.nan_to_num(tpx, nan=1e9) - b.pixel, axis=1)
            checked += 1
            wrong += int(tid[int(np.argmin(d))] != b.id)
    # pick-up: frames from a fixture's entering (whole disc inside) to its first use
    inside = [
        {t[0] for t in ft.get(name, []) if t[3]} for name in run.names
    ]  # per frame, IDs fully inside
    pickups: list[int] = []
    never: list[int] = []
    for k in range(1, len(inside)):
        for fid in inside[k] - inside[k - 1]:
            j = k
            while j < len(inside) and fid in inside[j] and fid not in used_by_frame[j]:
                j += 1
            if j < len(inside) and fid in inside[j]:
                pickups.append(j - k)
            else:
                never.append(fid)
    return {
        "ids_checked": checked,
        "wrong_ids": wrong,
        "used_not_fully_inside": used_outside,
        "pickup_frames": pickups,
        "entered_not_picked_up": never,
    }
