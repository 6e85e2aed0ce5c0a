"""File formats: camera and map files, photographs, survey tables and result writers."""

from camvlp.errors import InputError
from camvlp.io.files import load_camera, load_map, save_camera, save_map
from camvlp.io.images import load_image

__all__ = ["InputError", "load_camera", "load_image", "load_map", "save_camera", "save_map"]
