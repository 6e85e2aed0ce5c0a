"""File formats: camera files and map files (read as text by :mod:`camvlp.io.textfiles`).

Every loader raises :class:`InputError` (a ValueError) with one readable line that names
the file and, where it applies, the fixture or key at fault.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from camvlp.errors import InputError
from camvlp.io.atomic import StagedOutputs, strict_json, write_text_atomic
from camvlp.io.limits import limit
from camvlp.io.textfiles import expect_mapping, read_mapping
from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.linecode import FrameFormat

__all__ = [
    "camera_from_dict",
    "load_camera",
    "load_map",
    "map_from_dict",
    "save_camera",
    "save_map",
]


#: Largest magnitude of any number in a camera or map file (a coordinate, a focal length...).
MAX_MAGNITUDE = 1e9
#: Largest image_width or image_height of a camera file, pixels.
MAX_SIDE_PX = 1_000_000


def _matrix(value: Any, shape: tuple[int, ...] | None, key: str, path: str | Path) -> np.ndarray:
    """A matrix given as nested lists, a flat list, or OpenCV's {rows, cols, data}."""
    if isinstance(value, dict) and "data" in value:
        value = value["data"]
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{key} must be numbers", path) from None
    if arr.dtype == object or not np.all(np.isfinite(arr)):
        raise InputError(f"{key} must be finite numbers", path)
    if arr.size and float(np.abs(arr).max()) > MAX_MAGNITUDE:
        raise InputError(f"{key} has a number beyond +-{MAX_MAGNITUDE:g}", path)
    if shape is not None:
        if arr.size != int(np.prod(shape)):
            raise InputError(f"{key} must have {int(np.prod(shape))} numbers, got {arr.size}", path)
        arr = arr.reshape(shape)
    return arr


def _number(
    value: Any, key: str, path: Path, *, positive: bool = False, most: float = MAX_MAGNITUDE
) -> float:
    """``value`` as a float: a finite number of magnitude at most ``most`` (positive if asked)."""
    kind = "positive number" if positive else "number"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{key} must be a {kind}, got {_short(value)}", path)
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v) or (positive and v <= 0):
        raise InputError(f"{key} must be a finite {kind}, got {_short(value)}", path)
    if abs(v) > most:
        raise InputError(f"{key} must be at most {most:g}, got {_short(value)}", path)
    return v


def _integer(value: Any, key: str, path: Path, *, most: int) -> int:
    """``value`` as a positive integer of at most ``most`` (5184.0 passes; 5184.5 does not)."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(f"{key} must be a positive integer, got {_short(value)}", path)
    if value > most:
        raise InputError(f"{key} must be at most {most:,}, got {_short(value)}", path)
    return value


def _short(value: Any) -> str:
    """A value for an error message: its repr, cut to 40 characters."""
    try:
        text = repr(value)
    except ValueError:  # an int too long to print
        text = f"an integer of {value.bit_length()} bits"
    return text if len(text) <= 40 else text[:37] + "..."


def load_camera(path: str | Path) -> Camera:
    """Load a camera file (OpenCV calibration YAML, plain YAML, or JSON).

    Keys: ``image_width``, ``image_height`` (pixels); ``camera_matrix`` (3 x 3), or
    ``focal_length_px`` with an optional ``principal_point`` (``[cx, cy]`` or ``centre``
    for the image centre, which also overrides a matrix's cx, cy); optional
    ``distortion_coefficients`` (1 x N, OpenCV order), ``row_time_s`` (seconds between
    sensor rows), ``mirrored`` (bool), ``readout`` (``rows``, ``columns``, ``rows-reversed`` or
    ``columns-reversed``), ``tone_gamma`` (the camera's tone curve, e.g. 2.2).

    Raises
    ------
    InputError
        Missing or malformed file, naming the file and the key.
    """
    return camera_from_dict(read_mapping(path, "camera"), Path(path))


#: The keys a camera file, a map, its frame and its fixtures are read for.
CAMERA_KEYS = (
    "image_width",
    "image_height",
    "camera_matrix",
    "focal_length_px",
    "principal_point",
    "distortion_coefficients",
    "row_time_s",
    "mirrored",
    "readout",
    "tone_gamma",
)
MAP_KEYS = ("units", "frame", "fixtures", "up")
FRAME_KEYS = (
    "mode",
    "line_code",
    "preamble",
    "id_bits",
    "check_bits",
    "postamble",
    "chip_rate_hz",
    "reuse",
)
FIXTURE_KEYS = ("id", "position", "diameter", "normal", "frequency_hz")


def _misspelled(data: Mapping[str, Any], known: tuple[str, ...], where: str, path) -> None:
    """Refuse a key of ``data`` that is not one of ``known`` but reads almost as one (a typo
    such as ``diametre``, which would otherwise be ignored without a word); other keys
    (notes a file may carry) are left alone."""
    for key in data:
        if isinstance(key, str) and key not in known:
            close = difflib.get_close_matches(key, known, n=1, cutoff=0.8)
            if close:
                raise InputError(f"{where}unknown key {key!r} (did you mean {close[0]!r}?)", path)


def camera_from_dict(data: Mapping[str, Any], source: str | Path = "camera") -> Camera:
    """Build a camera from an already-parsed mapping with a camera file's keys.

    The one validation path of :func:`load_camera` (which calls it), for cameras that arrive
    parsed (e.g. as JSON over HTTP).  ``source`` names the input in error messages.

    Raises
    ------
    InputError
        A missing or malformed key, naming ``source`` and the key.
    """
    p = source
    expect_mapping(data, "camera", p)
    _misspelled(data, CAMERA_KEYS, "", p)
    try:
        width = _integer(data.get("image_width"), "image_width", p, most=MAX_SIDE_PX)
        height = _integer(data.get("image_height"), "image_height", p, most=MAX_SIDE_PX)
    except InputError:
        if "image_width" not in data or "image_height" not in data:
            raise InputError("camera file needs image_width and image_height", p) from None
        raise
    max_pixels = limit("CAMVLP_MAX_PIXELS")
    if width * height > max_pixels:
        raise InputError(
            f"camera is {width} x {height} = {width * height:,} pixels, over the limit of "
            f"{max_pixels:,} (set CAMVLP_MAX_PIXELS)",
            p,
        )
    if "camera_matrix" in data:
        k = _matrix(data["camera_matrix"], (3, 3), "camera_matrix", p)
    elif "focal_length_px" in data:
        f = _number(data["focal_length_px"], "focal_length_px", p, positive=True)
        k = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
    else:
        raise InputError("camera file needs camera_matrix or focal_length_px", p)
    pp = data.get("principal_point")
    if isinstance(pp, str):
        if pp.lower() not in ("centre", "center"):
            raise InputError(f"principal_point must be [cx, cy] or 'centre', got {pp!r}", p)
        k[0, 2], k[1, 2] = (width - 1) / 2, (height - 1) / 2
    elif pp is not None:
        k[0, 2], k[1, 2] = _matrix(pp, (2,), "principal_point", p)
    cx, cy = float(k[0, 2]), float(k[1, 2])
    if not (-0.5 * width <= cx <= 1.5 * width and -0.5 * height <= cy <= 1.5 * height):
        # (a lens shifted off the sensor's middle, or a crop, moves it by a share of a side)
        raise InputError(
            f"the principal point ({cx:g}, {cy:g}) lies half the image or more outside the "
            f"{width} x {height} image: check its numbers (pixels, x then y)",
            p,
        )
    dist_value = data.get("distortion_coefficients")
    dist = (
        np.zeros(0)
        if dist_value is None
        else _matrix(dist_value, None, "distortion_coefficients", p)
    )
    row_time = data.get("row_time_s")
    if row_time is not None:
        row_time = _number(row_time, "row_time_s", p, positive=True, most=1.0)
    mirrored = data.get("mirrored", False)
    if not isinstance(mirrored, bool):
        raise InputError(f"mirrored must be true or false, got {mirrored!r}", p)
    tone = data.get("tone_gamma")
    if tone is not None:
        tone = _number(tone, "tone_gamma", p, positive=True)
    try:
        return Camera(
            width, height, k, dist.reshape(-1), row_time, mirrored, data.get("readout"), tone
        )
    except ValueError as exc:
        raise InputError(str(exc), p) from None


def save_camera(camera: Camera, path: str | Path, *, extra: dict | None = None) -> None:
    """Write a camera file: OpenCV FileStorage YAML (``.yaml``/``.yml``) or JSON (``.json``).

    ``extra`` adds scalar keys (e.g. ``rms_px``) to the file.
    """
    p = Path(path)
    fields: dict[str, Any] = {
        "image_width": camera.width,
        "image_height": camera.height,
        "camera_matrix": camera.matrix,
        "distortion_coefficients": camera.distortion.reshape(1, -1)
        if camera.distortion.size
        else np.zeros((1, 5)),
    }
    if camera.row_time_s is not None:
        fields["row_time_s"] = float(camera.row_time_s)
    if camera.mirrored:
        fields["mirrored"] = 1
    if camera.readout:
        fields["readout"] = camera.readout
    if camera.tone_gamma is not None:
        fields["tone_gamma"] = float(camera.tone_gamma)
    fields.update(extra or {})
    if p.suffix.lower() == ".json":
        out = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in fields.items()}
        if camera.mirrored:
            out["mirrored"] = True
        write_text_atomic(p, strict_json(out, indent=2) + "\n")
        return
    with StagedOutputs() as staged:  # whole or not at all
        tmp = staged.file(p)
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        for key, value in fields.items():
            fs.write(key, value)
        fs.release()
        if camera.mirrored:  # FileStorage writes ints; say it as YAML's true for our loader
            tmp.write_text(tmp.read_text().replace("mirrored: 1", "mirrored: true"))


def load_map(path: str | Path) -> FixtureMap:
    """Load a map file (YAML or JSON); see ``docs/formats.md``.

    Raises
    ------
    InputError
        Missing or malformed file, a duplicate ID, an ID that does not fit the frame, a
        missing or non-numeric position, an ambiguous frame format; naming the file and the
        fixture.
    """
    return map_from_dict(read_mapping(path, "map"), Path(path))


def map_from_dict(data: Mapping[str, Any], source: str | Path = "map") -> FixtureMap:
    """Build a fixture map from an already-parsed mapping with a map file's keys.

    What :func:`camera_from_dict` is to cameras, for maps: :func:`load_map` calls it;
    it raises InputError as :func:`load_map` does, naming ``source`` and the fixture at fault.
    """
    p = source
    expect_mapping(data, "map", p)
    _misspelled(data, MAP_KEYS, "", p)
    units = data.get("units", "m")
    frame_spec = data.get("frame") or {}
    mode, frame, chip_rate = _frame_from_dict(frame_spec, p)
    reuse = frame_spec.get("reuse", False)
    if not isinstance(reuse, bool):
        raise InputError(f"frame reuse must be true or false, got {_short(reuse)}", p)
    entries = data.get("fixtures")
    if not isinstance(entries, list) or not entries:
        raise InputError("map needs a non-empty list 'fixtures'", p)
    seen: set[int] | None = None if reuse else set()
    fixtures = [_fixture_from_dict(e, i, mode, frame, seen, p) for i, e in enumerate(entries)]
    up = None
    if data.get("up") is not None:
        up = _matrix(data["up"], (3,), "up", p)
        if not np.any(up):
            raise InputError("up must be a non-zero 3-vector (the map's up direction)", p)
    try:
        return FixtureMap(
            tuple(fixtures),
            units=str(units),
            mode=mode,
            frame=frame,
            source=str(p),
            up=up,
            chip_rate_hz=chip_rate,
            reuse=reuse,
        )
    except ValueError as exc:
        raise InputError(str(exc), p) from None


def _frame_from_dict(frame_spec: Any, p: str | Path) -> tuple[str, FrameFormat, float | None]:
    """A map's ``frame`` key: the line code's mode, its frame format and chip rate (Hz)."""
    expect_mapping(frame_spec, "map frame", p)
    _misspelled(frame_spec, FRAME_KEYS, "frame: ", p)
    mode = str(frame_spec.get("mode", frame_spec.get("line_code", "manchester"))).lower()
    if mode not in ("manchester", "frequency"):
        raise InputError(f"frame mode must be manchester or frequency, got {mode!r}", p)
    for key, default in (("preamble", "111"), ("postamble", "00")):
        # YAML reads an unquoted 00 as the number 0: insist on strings, never guess
        if not isinstance(frame_spec.get(key, default), str):
            raise InputError(
                f'frame {key} must be a quoted string of 0 and 1 such as "{default}", '
                f"got {frame_spec[key]!r}",
                p,
            )
    try:
        frame = FrameFormat(
            frame_spec.get("preamble", "111"),
            frame_spec.get("id_bits", 4),
            frame_spec.get("postamble", "00"),
            frame_spec.get("check_bits", 0),
        )
    except ValueError as exc:
        raise InputError(str(exc), p) from None
    chip_rate = None
    if frame_spec.get("chip_rate_hz") is not None:
        chip_rate = _number(frame_spec["chip_rate_hz"], "frame chip_rate_hz", p, positive=True)
    return mode, frame, chip_rate


def _fixture_from_dict(
    entry: Any, index: int, mode: str, frame: FrameFormat, seen: set[int] | None, p: str | Path
) -> Fixture:
    """The map's ``index``-th fixture (from 0): its id (added to the ``seen`` ones; None: a
    map whose IDs may repeat), position and optional keys."""
    where = f"fixture #{index + 1}"
    expect_mapping(entry, f"map {where}", p)
    fid = entry.get("id", index if mode == "frequency" else None)
    if isinstance(fid, bool) or not isinstance(fid, int):
        raise InputError(f"{where} needs an integer id, got {_short(fid)}", p)
    where = f"fixture {fid}"
    _misspelled(entry, FIXTURE_KEYS, f"{where}: ", p)
    if seen is not None:
        if fid in seen:
            raise InputError(
                f"duplicate ID in {where} (a map that gives one ID to many fixtures says "
                "reuse: true in its frame)",
                p,
            )
        seen.add(fid)
    if mode == "manchester":
        try:
            frame.check_id(fid)
        except ValueError as exc:
            raise InputError(f"{exc} in {where}", p) from None
    pos = entry.get("position")
    if pos is None:
        raise InputError(f"{where} has no position", p)
    if not (isinstance(pos, list) and len(pos) == 3):
        raise InputError(f"{where}: position must be three numbers, got {_short(pos)}", p)
    pos = [_number(v, f"{where}: position", p) for v in pos]
    kwargs: dict[str, Any] = {}
    for key in ("diameter", "frequency_hz"):
        if entry.get(key) is not None:
            kwargs[key] = _number(entry[key], f"{where}: {key}", p, positive=True)
    if entry.get("normal") is not None:
        kwargs["normal"] = _matrix(entry["normal"], (3,), f"{where}: normal", p)
    try:
        return Fixture(fid, np.asarray(pos, dtype=float), **kwargs)
    except ValueError as exc:
        raise InputError(f"{where}: {exc}", p) from None


def save_map(fixture_map: FixtureMap, path: str | Path) -> None:
    """Write a map as YAML (or JSON for a ``.json`` path)."""
    fm = fixture_map
    frame: dict[str, Any] = {"mode": fm.mode}
    if fm.mode == "manchester":
        frame.update(
            preamble=fm.frame.preamble, id_bits=fm.frame.id_bits, postamble=fm.frame.postamble
        )
        if fm.frame.check_bits:
            frame["check_bits"] = fm.frame.check_bits
        if fm.chip_rate_hz is not None:
            frame["chip_rate_hz"] = float(fm.chip_rate_hz)
        if fm.reuse:
            frame["reuse"] = True
    entries = []
    for f in fm.fixtures:
        e: dict[str, Any] = {"id": f.id, "position": [float(v) for v in f.position]}
        if f.diameter is not None:
            e["diameter"] = float(f.diameter)
        if f.normal is not None:
            e["normal"] = [float(v) for v in f.normal]
        if f.frequency_hz is not None:
            e["frequency_hz"] = float(f.frequency_hz)
        entries.append(e)
    data: dict[str, Any] = {"units": fm.units, "frame": frame}
    if fm.up is not None:
        data["up"] = [float(v) for v in fm.up]
    data["fixtures"] = entries
    p = Path(path)
    if p.suffix.lower() == ".json":
        write_text_atomic(p, strict_json(data, indent=2) + "\n")
    else:
        write_text_atomic(p, yaml.safe_dump(data, sort_keys=False, default_flow_style=None))
