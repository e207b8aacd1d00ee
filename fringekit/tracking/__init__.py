"""Tracking: every contact's load read off a stream of frames (``fringekit track``).

:func:`track` -> :class:`Track` follows every contact through a stream
(:class:`~fringekit.tracking.tracker.Tracker`: a warm-started fit per frame; recovery,
touch and release within the frame); :func:`library_frames` writes frames of known loads
synthesised from a library. The frame sources (:mod:`fringekit.tracking.source`):
:func:`open_source` opens a folder of images, a video file or a camera as a
:class:`FrameSource` of :class:`RawFrame` objects; :func:`write_video`
(:mod:`fringekit.tracking.write`) writes frames to a video file; :class:`RestFrames`
(:mod:`fringekit.inversion.rest`) takes the light of the sensor at rest off every frame
(``--reference``).
"""

from fringekit.inversion.rest import RestFrames
from fringekit.tracking.frame import TrackedFrame
from fringekit.tracking.source import (
    IMAGE_SUFFIXES,
    VIDEO_SUFFIXES,
    CameraSource,
    FolderSource,
    FrameSource,
    RawFrame,
    VideoSource,
    open_source,
)
from fringekit.tracking.stream import TRACK_COLUMNS, Track, track
from fringekit.tracking.synthetic import library_frames
from fringekit.tracking.tracker import Tracker
from fringekit.tracking.write import write_video

__all__ = [
    "IMAGE_SUFFIXES",
    "TRACK_COLUMNS",
    "Track",
    "TrackedFrame",
    "Tracker",
    "library_frames",
    "track",
    "VIDEO_SUFFIXES",
    "CameraSource",
    "FolderSource",
    "FrameSource",
    "RawFrame",
    "RestFrames",
    "VideoSource",
    "open_source",
    "write_video",
]
