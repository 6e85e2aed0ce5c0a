"""The things camvlp reasons about: cameras and poses, fixture maps, the line code, the readout.

Types and conventions only: no file I/O, no image processing.
"""
