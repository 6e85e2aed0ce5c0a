"""Stages 4 and 5, identify and solve: the decoded IDs looked up in the map
(:mod:`~camvlp.pipeline.identified`), look-alikes told apart by the pose
(:mod:`~camvlp.pipeline.identify.by_pose`), IDs read twice and the readout's direction decided
by the pose when the stripes fit both (:mod:`~camvlp.pipeline.identify.decide`); the stage
itself in :mod:`~camvlp.pipeline.identify.stage`."""
