"""The locator, in stage order: prepare -> detect (the lights) -> profile -> decode ->
identify -> solve -> report (:mod:`~camvlp.pipeline.stages`), and
:func:`~camvlp.pipeline.locate.locate` that runs them on one photograph.

Sub-packages hold what a stage needs beyond its driver: :mod:`~camvlp.pipeline.detect` (the
lit regions, one light each, at full resolution), :mod:`~camvlp.pipeline.lamp` (what a
glowing, joined or clipping lamp asks), :mod:`~camvlp.pipeline.decode` (the decoders),
:mod:`~camvlp.pipeline.identify` (IDs told by the pose, the readout's direction) and
:mod:`~camvlp.pipeline.track` (a video's frames with a memory).
"""
