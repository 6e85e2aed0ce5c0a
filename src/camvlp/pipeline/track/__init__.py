"""Tracking a camera along a video: each frame located with the previous ones' help
(:mod:`~camvlp.pipeline.track.tracker`), fixtures predicted in the image
(:mod:`~camvlp.pipeline.track.predict`) and associated from frame to frame
(:mod:`~camvlp.pipeline.track.assoc`), the frame's pose solved with the track's prior
(:mod:`~camvlp.pipeline.track.solve`, :mod:`~camvlp.pipeline.track.offsets`), the path
smoothed by a Kalman filter (:mod:`~camvlp.pipeline.track.motion`,
:mod:`~camvlp.pipeline.track.kalman`)."""

from camvlp.pipeline.track.records import TrackedFixture, TrackFrame, TrackSettings
from camvlp.pipeline.track.tracker import Tracker

__all__ = ["TrackFrame", "TrackSettings", "TrackedFixture", "Tracker"]
