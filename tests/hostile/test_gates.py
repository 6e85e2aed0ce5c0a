"""Unit tests of the gates themselves: limits, the image gate's conversions and header reader,
staged outputs, strict JSON, and the bounded frame-format ambiguity check."""

from __future__ import annotations

import json
import os
import stat

import cv2
import numpy as np
import pytest
from bad_inputs import jpeg_header_only, png_header_only, tiff_header_only

from camvlp.errors import InputError, one_line
from camvlp.io.atomic import StagedOutputs, check_output_dir, check_output_file, strict_json
from camvlp.io.image_header import image_header
from camvlp.io.images import as_image, decode_image
from camvlp.io.limits import limit, read_regular_file
from camvlp.model.linecode import FrameFormat

# ------------------------------------------------------------------ limits and files


def test_limit_reads_the_environment_and_refuses_nonsense(monkeypatch):
    monkeypatch.delenv("CAMVLP_MAX_PIXELS", raising=False)
    assert limit("CAMVLP_MAX_PIXELS") == 200_000_000
    monkeypatch.setenv("CAMVLP_MAX_PIXELS", "1_000")
    assert limit("CAMVLP_MAX_PIXELS") == 1000
    assert limit("CAMVLP_MAX_PIXELS", 5) == 5
    for bad in ("-3", "0", "lots", "9" * 30):
        monkeypatch.setenv("CAMVLP_MAX_PIXELS", bad)
        with pytest.raises(InputError, match="CAMVLP_MAX_PIXELS"):
            limit("CAMVLP_MAX_PIXELS")


def test_pixel_limit_from_the_environment_applies_to_photos(tmp_path, monkeypatch):
    _, buf = cv2.imencode(".png", np.zeros((30, 40), np.uint8))
    path = tmp_path / "p.png"
    path.write_bytes(buf.tobytes())
    monkeypatch.setenv("CAMVLP_MAX_PIXELS", "1199")
    with pytest.raises(InputError, match="40 x 30 = 1,200 pixels, over the limit of 1,199"):
        decode_image(path.read_bytes())
    monkeypatch.setenv("CAMVLP_MAX_PIXELS", "1200")
    assert decode_image(path.read_bytes()).shape == (30, 40)


def test_read_regular_file_refuses_what_is_not_one(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    with pytest.raises(InputError, match="named pipe"):
        read_regular_file(fifo, "photo", 100)
    with pytest.raises(InputError, match="device"):
        read_regular_file("/dev/null", "photo", 100)
    with pytest.raises(InputError, match="directory"):
        read_regular_file(tmp_path, "photo", 100)
    big = tmp_path / "big"
    big.write_bytes(b"x" * 101)
    with pytest.raises(InputError, match="101 bytes, over the limit of 100"):
        read_regular_file(big, "photo", 100)
    assert read_regular_file(big, "photo", 101) == b"x" * 101


def test_one_line_escapes_control_characters():
    assert one_line("a\nb\tc\x1b[31m") == "a\\nb\\tc\\x1b[31m"
    assert str(InputError("bad", "x\ny.jpg")) == "bad (x\\ny.jpg)"


# ------------------------------------------------------------------ image gate


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        (png_header_only(100_000, 100_000), ("png", 100_000, 100_000)),
        (jpeg_header_only(30_000, 20_000), ("jpeg", 30_000, 20_000)),
        (tiff_header_only(15_000, 12_000), ("tiff", 15_000, 12_000)),
    ],
)
def test_header_is_read_without_decoding(data, expected):
    header = image_header(data)
    assert (header.format, header.width, header.height) == expected
    assert len(data) < 20_000
    with pytest.raises(InputError, match="over the limit"):
        decode_image(data)


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".tiff", ".bmp", ".webp"])
def test_header_agrees_with_the_decoder(suffix):
    img = np.random.default_rng(3).integers(0, 255, (37, 53, 3), dtype=np.uint8)
    ok, buf = cv2.imencode(suffix, img)
    assert ok
    header = image_header(buf.tobytes())
    assert (header.width, header.height) == (53, 37)
    assert decode_image(buf.tobytes()).shape == (37, 53, 3)


def test_unknown_format_and_cut_headers_are_refused():
    with pytest.raises(InputError, match="not an image, or a corrupt one: camvlp reads PNG"):
        image_header(b"GIF89a" + bytes(100))
    with pytest.raises(InputError, match=r"cut short|malformed"):
        image_header(b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR\x00")
    with pytest.raises(InputError, match="malformed JPEG"):
        image_header(b"\xff\xd8\xff\xda\x00\x02")
    for brand in (b"heic", b"mif1", b"avif"):  # a phone's HEIF photo: told what to do
        with pytest.raises(InputError, match=r"HEIF, HEIC and AVIF .* as JPEG or PNG"):
            image_header(b"\x00\x00\x00\x18ftyp" + brand + bytes(100))


def test_as_image_conversions():
    assert as_image(np.array([[True, False]])).tolist() == [[255, 0]]
    small = np.array([[-5, 0, 200]], np.int16)
    assert as_image(small).dtype == np.uint8 and as_image(small).tolist() == [[0, 0, 200]]
    mid = np.array([[1000, 60000]], np.int32)
    assert as_image(mid).dtype == np.uint16 and as_image(mid).tolist() == [[1000, 60000]]
    wide = np.array([[0, 2**20, 2**21]], np.int64)
    assert as_image(wide).tolist() == [[0, 32768, 65535]]
    unit = np.array([[0.0, 0.5, 1.0]])
    assert as_image(unit).tolist() == [[0, 32768, 65535]]
    assert as_image(np.array([[0.0, 10.0]], np.float16)).tolist() == [[0, 65535]]
    assert as_image(np.zeros((4, 5, 4), np.uint8)).shape == (4, 5, 3)
    assert as_image(np.zeros((4, 5, 2), np.uint16)).shape == (4, 5)
    for bad in (
        np.zeros((4, 5), complex),
        np.zeros((0, 5)),
        np.zeros((4,)),
        np.full((2, 2), np.inf),
    ):
        with pytest.raises(InputError):
            as_image(bad)


# ------------------------------------------------------------------ outputs


def test_staged_outputs_commit_together(tmp_path):
    with StagedOutputs() as out:
        a = out.file(tmp_path / "a.txt")
        a.write_text("A")
        folder = out.folder(tmp_path / "pics")
        (folder / "1.png").write_bytes(b"1")
        assert not (tmp_path / "a.txt").exists()  # nothing in place before the commit
    assert (tmp_path / "a.txt").read_text() == "A"
    assert (tmp_path / "pics" / "1.png").read_bytes() == b"1"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "pics"]


def test_staged_outputs_leave_nothing_on_failure(tmp_path):
    with pytest.raises(RuntimeError), StagedOutputs() as out:
        out.file(tmp_path / "a.txt").write_text("A")
        (out.folder(tmp_path / "pics") / "1.png").write_bytes(b"1")
        raise RuntimeError("the work failed")
    assert list(tmp_path.iterdir()) == []


def test_staged_outputs_roll_back_when_a_rename_fails(tmp_path):
    (tmp_path / "b.txt").mkdir()  # b.txt cannot be replaced by a file
    with pytest.raises(InputError, match="cannot write output"), StagedOutputs() as out:
        out.file(tmp_path / "a.txt").write_text("A")
        out.file(tmp_path / "b.txt").write_text("B")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.txt"]


def test_output_checks(tmp_path):
    existing = tmp_path / "f"
    existing.write_text("x")
    with pytest.raises(InputError, match="existing file"):
        check_output_dir(existing, "--debug-dir")
    with pytest.raises(InputError, match="does not exist"):
        check_output_file(tmp_path / "missing" / "a.png", "--out")
    with pytest.raises(InputError, match="folder or a special file"):
        check_output_file(tmp_path, "--out")
    with pytest.raises(InputError, match="must end in"):
        check_output_file(tmp_path / "a.gif", "--out", (".png",))
    assert check_output_dir(tmp_path / "new", "--out") == tmp_path / "new"


def test_strict_json_writes_null_for_nan_and_infinity():
    text = strict_json(
        {"a": float("nan"), "b": [np.inf, 1.5], "c": np.array([np.nan, 2.0]), "d": np.float32(3)}
    )
    assert json.loads(text, parse_constant=pytest.fail) == {
        "a": None,
        "b": [None, 1.5],
        "c": [None, 2.0],
        "d": 3.0,
    }


# ------------------------------------------------------------------ frame-format ambiguity


def _min_distance_brute(frame: FrameFormat) -> int:
    """Every rotation of every ID against every other ID's frame, materialised."""
    n = frame.n_chips
    idx = (np.arange(n)[:, None] + np.arange(n)[None, :]) % n
    rot = frame.codebook[:, idx].reshape(-1, n)
    owner = np.repeat(np.arange(frame.n_ids), n)
    d = (frame.codebook[:, None, :] != rot[None, :, :]).sum(axis=2)
    d[owner[None, :] == np.arange(frame.n_ids)[:, None]] = n + 1
    return int(d.min())


@pytest.mark.parametrize(
    ("pre", "bits", "post"),
    [("111", 4, "00"), ("1111", 5, "000"), ("1111", 6, "00"), ("111", 3, "0"), ("11", 2, "0")],
)
def test_min_distance_matches_the_brute_force(pre, bits, post):
    frame = FrameFormat(pre, bits, post)
    assert frame.min_distance == _min_distance_brute(frame) > 0


def test_twelve_id_bits_are_checked_within_bounds():
    with pytest.raises(ValueError, match="ambiguous"):
        FrameFormat("111", 12, "00")  # 4096 IDs x 34 rotations: chunked, ~100 MB at most
    with pytest.raises(ValueError, match="at most 32"):
        FrameFormat("1" * 30, 4, "00")
