"""Stage 4, identify: the decoded IDs looked up in the map, look-alikes told apart by the pose
(:mod:`~camvlp.pipeline.identify.by_pose`), and the readout's direction decided by the pose
when the stripes fit both (:mod:`~camvlp.pipeline.identify.lookup`)."""
