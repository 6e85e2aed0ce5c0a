"""Measuring camvlp and cameras: the error study, survey evaluation, camera calibration."""
