"""What a lamp's look asks beyond a plain striped disc: a glow around it, a hot core, glows
that join the neighbours', a disc that clips.

The looks share one model: a light shines its radially symmetric shape times its own
waveform, through the sensor's clipping (:mod:`~camvlp.pipeline.lamp.light_wave`).  A glowing
light is centred on its shape (:mod:`~camvlp.pipeline.lamp.glow`,
:mod:`~camvlp.pipeline.lamp.radial`), lights whose glows join are fitted together
(:mod:`~camvlp.pipeline.lamp.crowded`), and a light whose disc clips in its dark chips too is
read from its glow (:mod:`~camvlp.pipeline.decode.glow_split`).
"""
