"""Stages 2 and 3, profile and decode: each fixture's row profile, and its ID.

Manchester maps: the run-length decoder (:mod:`~camvlp.pipeline.decode.run_decode`, on the
runs of :mod:`~camvlp.pipeline.decode.runs` and the chips of
:mod:`~camvlp.pipeline.decode.chips`) for the clear cases, the sensor's forward model fitted
to every ID (:mod:`~camvlp.pipeline.decode.model`, with the photo-wide parameters of
:mod:`~camvlp.pipeline.decode.photo_model`) for the rest, both driven by
:mod:`~camvlp.pipeline.decode.manchester`.  Frequency maps: each light held against a
beacon's forward model (:mod:`~camvlp.pipeline.decode.beacon`) at each map frequency
(:mod:`~camvlp.pipeline.decode.beacon_match`), driven by
:mod:`~camvlp.pipeline.decode.frequency`.
"""
