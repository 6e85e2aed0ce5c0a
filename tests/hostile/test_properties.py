"""Property-based tests: whatever arrives, camvlp answers or raises InputError, in bounded memory.

Hypothesis draws the inputs (image arrays of any type and shape, arbitrary objects, random and
structured camera and map files, damaged photos, option strings); each example runs under
``tracemalloc`` with a memory ceiling.  Examples are derandomized so CI is reproducible.
"""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path
from unittest import mock

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import camvlp
from camvlp.cli import main
from camvlp.io import load_camera, load_image, load_map
from camvlp.io.files import CAMERA_KEYS, MAP_KEYS

#: Hypothesis settings shared by the tests: reproducible, modest, explicit deadline.
FAST = settings(
    max_examples=60,
    deadline=5000,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

#: Peak Python allocation allowed per example, bytes.
MEMORY_CEILING = 64 * 1024 * 1024

CAMERA = camvlp.Camera(16, 12, np.array([[20.0, 0, 7.5], [0, 20.0, 5.5], [0, 0, 1]]))
FIXTURES = camvlp.FixtureMap(
    tuple(
        camvlp.Fixture(i, np.array(p, float), diameter=0.15)
        for i, p in ((5, (0.5, 0.5, 2.7)), (6, (0.5, -0.5, 2.7)), (9, (-0.5, -0.5, 2.7)))
    )
)


def _bounded(func, *args, **kwargs):
    """Call ``func`` under tracemalloc; fail when its peak allocation passes the ceiling."""
    tracemalloc.start()
    try:
        return func(*args, **kwargs)
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert peak < MEMORY_CEILING, f"peak {peak / 1e6:.0f} MB"


# ------------------------------------------------------------------ locate's array input

dtypes = st.one_of(
    hnp.boolean_dtypes(),
    hnp.integer_dtypes(),
    hnp.unsigned_integer_dtypes(),
    hnp.floating_dtypes(),
    hnp.complex_number_dtypes(),
)
shapes = hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=16)


@FAST
@given(hnp.arrays(dtypes, shapes))
def test_locate_any_array_answers_or_raises_input_error(image):
    try:
        result = _bounded(camvlp.locate, image, CAMERA, FIXTURES)
    except camvlp.InputError as exc:
        assert "\n" not in str(exc)
        return
    assert isinstance(result, camvlp.LocateResult)
    assert image.shape[:2] == (12, 16)  # only an image of the camera's size gets this far


@FAST
@given(
    st.one_of(
        st.none(),
        st.integers(),
        st.floats(),
        st.text(max_size=20),
        st.binary(max_size=20),
        st.lists(st.lists(st.integers(-300, 300), max_size=17), max_size=13),
        st.lists(st.lists(st.floats(), max_size=16), max_size=12),
        st.dictionaries(st.text(max_size=3), st.integers(), max_size=3),
    )
)
def test_locate_any_object_answers_or_raises_input_error(obj):
    try:
        _bounded(camvlp.locate, obj, CAMERA, FIXTURES)
    except camvlp.InputError as exc:
        assert "\n" not in str(exc)


@pytest.mark.parametrize("camera", [None, "camera.yaml", 3, CAMERA.matrix])
def test_locate_refuses_a_camera_that_is_not_one(camera):
    with pytest.raises(camvlp.InputError, match="camera must be a Camera"):
        camvlp.locate(np.zeros((12, 16), np.uint8), camera, FIXTURES)


# ------------------------------------------------------------------ camera and map files

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**40), 10**40),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=20,
)
camera_keys = st.sampled_from(CAMERA_KEYS)
map_keys = st.sampled_from(MAP_KEYS)
fixture = st.fixed_dictionaries(
    {},
    optional={
        "id": values,
        "position": st.one_of(values, st.lists(scalars, min_size=3, max_size=3)),
        "diameter": scalars,
        "normal": values,
        "frequency_hz": scalars,
    },
)
frame = st.fixed_dictionaries(
    {},
    optional={
        "mode": st.sampled_from(["manchester", "frequency", "x"]),
        "preamble": st.one_of(st.text("01", max_size=40), scalars),
        "id_bits": st.one_of(st.integers(-2, 40), scalars),
        "postamble": st.one_of(st.text("01", max_size=40), scalars),
    },
)


def _write(path: Path, doc: object) -> bool:
    """Write ``doc`` as JSON or YAML (by suffix); False when it cannot be represented."""
    try:
        if path.suffix == ".json":
            path.write_text(json.dumps(doc))
        else:
            path.write_text(yaml.safe_dump(doc))
    except (ValueError, TypeError, yaml.YAMLError):
        return False
    return True


@FAST
@given(st.dictionaries(camera_keys, values, max_size=9), st.sampled_from([".json", ".yaml"]))
def test_camera_file_loads_or_raises_input_error(tmp_path, doc, suffix):
    path = tmp_path / f"camera{suffix}"
    if not _write(path, doc):
        return
    try:
        camera = _bounded(load_camera, path)
    except camvlp.InputError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    assert camera.width * camera.height <= 200_000_000
    assert np.all(np.isfinite(camera.matrix))


@FAST
@given(
    st.fixed_dictionaries(
        {"fixtures": st.one_of(values, st.lists(fixture, max_size=6))},
        optional={"units": st.sampled_from(["m", "cm", "mm", "km", 3]), "frame": frame},
    ),
    st.sampled_from([".json", ".yaml"]),
)
def test_map_file_loads_or_raises_input_error(tmp_path, doc, suffix):
    path = tmp_path / f"map{suffix}"
    if not _write(path, doc):
        return
    try:
        fixture_map = _bounded(load_map, path)
    except camvlp.InputError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    assert all(np.all(np.isfinite(f.position)) for f in fixture_map.fixtures)


@FAST
@given(st.binary(max_size=2000), st.sampled_from(["camera.yaml", "map.json", "map.yaml"]))
def test_random_bytes_as_a_camera_or_map_file(tmp_path, data, name):
    path = tmp_path / name
    path.write_bytes(data)
    loader = load_camera if name.startswith("camera") else load_map
    try:
        _bounded(loader, path)
    except camvlp.InputError as exc:
        assert "\n" not in str(exc)


# ------------------------------------------------------------------ photos


def _small_photo(suffix: str) -> bytes:
    rng = np.random.default_rng(7)
    img = (rng.random((24, 32, 3)) * 255).astype(np.uint8)
    ok, buf = cv2.imencode(suffix, img)
    assert ok
    return buf.tobytes()


PHOTOS = {s: _small_photo(s) for s in (".png", ".jpg", ".tiff", ".bmp", ".webp")}


@FAST
@given(
    st.sampled_from(sorted(PHOTOS)),
    st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), min_size=1, max_size=8),
    st.one_of(st.none(), st.integers(0, 10**6)),
)
def test_damaged_photo_loads_or_raises_input_error(tmp_path, capfd, suffix, edits, cut):
    data = bytearray(PHOTOS[suffix])
    for where, value in edits:
        data[where % len(data)] = value
    if cut is not None:
        data = data[: cut % len(data)]
    path = tmp_path / f"photo{suffix}"
    path.write_bytes(bytes(data))
    # the command line's case, a process of one thread, where the decoders' messages are
    # captured: idle threads other tests of this process leave (a server's pool) do not
    # write, but would send the decode down the path that cannot capture
    one_thread = mock.patch("camvlp.io.images.threading.active_count", return_value=1)
    try:
        with one_thread:
            image = _bounded(load_image, path)
    except camvlp.InputError as exc:
        assert "\n" not in str(exc)
    else:
        assert image.dtype in (np.uint8, np.uint16) and image.ndim in (2, 3)
    _, err = capfd.readouterr()
    assert err == "", err  # the decoders' messages are captured, never printed


# ------------------------------------------------------------------ option parsing

numbers_as_text = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**400), 10**400).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "0", "-0", "", " "]),
    st.text(max_size=12),
)


def _assert_one_line(code: int, err: str) -> None:
    lines = err.splitlines()
    if code == 0:
        assert not [ln for ln in lines if ln.startswith("error:")], lines
    else:
        assert code == 2, (code, lines)
        assert len(lines) == 1 and lines[0].startswith("error: "), lines


#: Fewer examples for whole command lines (each builds the CLI and may render).
CLI = settings(FAST, max_examples=30, deadline=10_000)


@CLI
@given(numbers_as_text, numbers_as_text)
def test_encode_options(capfd, fixture_id, chip_rate):
    code = main(["encode", fixture_id, "--chip-rate", chip_rate, "--json"])
    out, err = capfd.readouterr()
    _assert_one_line(code, err)
    if code == 0:
        json.loads(out, parse_constant=lambda c: pytest.fail(f"{c} in JSON"))


@CLI
@given(
    numbers_as_text,
    st.lists(numbers_as_text, min_size=1, max_size=4).map(",".join),
    st.lists(numbers_as_text, min_size=1, max_size=4).map(",".join),
)
def test_render_options(tmp_path, capfd, blur, position, euler):
    cam = tmp_path / "cam.yaml"
    cam.write_text("image_width: 32\nimage_height: 24\nfocal_length_px: 30\n")
    fmap = tmp_path / "map.yaml"
    fmap.write_text("fixtures:\n  - {id: 5, position: [0, 0, 3], diameter: 0.15}\n")
    out = tmp_path / "out"
    out.mkdir(exist_ok=True)
    argv = ["render", "--camera", str(cam), "--map", str(fmap), "--out", str(out / "r.png")]
    code = main([*argv, f"--blur={blur}", f"--position={position}", f"--euler={euler}"])
    _, err = capfd.readouterr()
    _assert_one_line(code, err)
    written = sorted(p.name for p in out.iterdir())
    assert written == (["r.json", "r.png"] if code == 0 else []), written
    if code == 0:
        truth = (out / "r.json").read_text()
        json.loads(truth, parse_constant=lambda c: pytest.fail(f"{c} in the truth JSON"))
        for p in out.iterdir():
            p.unlink()
