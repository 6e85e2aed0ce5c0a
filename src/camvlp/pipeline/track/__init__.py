"""Tracking a camera along a video: each frame located with the previous ones' help
(:mod:`~camvlp.pipeline.track.tracker`), fixtures associated from frame to frame
(:mod:`~camvlp.pipeline.track.assoc`), the path smoothed by a Kalman filter
(:mod:`~camvlp.pipeline.track.kalman`)."""

from camvlp.pipeline.track.records import TrackedFixture, TrackFrame, TrackSettings
from camvlp.pipeline.track.tracker import Tracker

__all__ = ["TrackFrame", "TrackSettings", "TrackedFixture", "Tracker"]
