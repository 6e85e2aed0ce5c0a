"""File formats: camera and map files, photographs, their gravity sidecars, survey tables and
result writers."""

from camvlp.errors import InputError
from camvlp.io.files import (
    camera_from_dict,
    load_camera,
    load_map,
    map_from_dict,
    save_camera,
    save_map,
)
from camvlp.io.images import decode_image, exif_readout, load_image
from camvlp.io.sidecar import PhotoSidecar, load_sidecar

__all__ = [
    "InputError",
    "PhotoSidecar",
    "camera_from_dict",
    "decode_image",
    "exif_readout",
    "load_camera",
    "load_image",
    "load_map",
    "load_sidecar",
    "map_from_dict",
    "save_camera",
    "save_map",
]
