"""The readout direction of an upright photo from its EXIF orientation tag."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from camvlp.io import exif_readout, load_image


def write_jpeg(path, pixels_rgb: np.ndarray, orientation: int | None) -> None:
    im = Image.fromarray(pixels_rgb)
    exif = Image.Exif()
    if orientation is not None:
        exif[0x0112] = orientation
    im.save(path, exif=exif.tobytes(), quality=95)


@pytest.mark.parametrize(
    ("tag", "readout"),
    [(3, "rows-reversed"), (6, "columns-reversed"), (8, "columns"), (None, None)],
)
def test_orientation_tag_gives_the_readout_of_the_upright_photo(tmp_path, tag, readout):
    # the stored (sensor) pixels: time runs down the rows, shown by a ramp 0 -> 255
    h, w = 48, 64
    ramp = np.repeat(np.linspace(0, 255, h)[:, None], w, axis=1).astype(np.uint8)
    path = tmp_path / "p.jpg"
    write_jpeg(path, np.dstack([ramp] * 3), tag)
    assert exif_readout(path) == readout
    if readout is None:
        return
    img = load_image(path)[:, :, 0].astype(float)
    # along the readout of the upright photo, in its direction, time (the ramp) grows
    axis = 0 if readout.startswith("rows") else 1
    profile = img.mean(axis=1 - axis)
    if readout.endswith("-reversed"):
        profile = profile[::-1]
    assert profile[-1] - profile[0] > 200


def test_orientation_one_says_nothing_of_the_sensor(tmp_path):
    """A photo stored upright (orientation 1) may have been turned by the phone itself: the
    Lumia 1020 stores its portrait photos so, their stripes vertical (sensor rows along the
    image's columns).  The tag gives no readout, so the stripes decide."""
    ramp = np.repeat(np.linspace(0, 255, 64)[None, :], 48, axis=0).astype(np.uint8)
    path = tmp_path / "p.jpg"
    write_jpeg(path, np.dstack([ramp] * 3), 1)
    assert exif_readout(path) is None


def test_no_exif_or_not_an_image(tmp_path):
    p = tmp_path / "x.jpg"
    p.write_bytes(b"not an image")
    assert exif_readout(p) is None
    assert exif_readout(tmp_path / "missing.jpg") is None
