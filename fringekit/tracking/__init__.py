"""Tracking: every contact's load read off a stream of frames (``fringekit track``).

The frame sources of :mod:`fringekit.tracking.source`: :func:`open_source` opens a folder
of images, a video file or a camera as a :class:`FrameSource` of :class:`RawFrame`
objects; :func:`write_video` (:mod:`fringekit.tracking.write`) writes frames to a video
file.
"""

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
from fringekit.tracking.write import write_video

__all__ = [
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "CameraSource",
    "FolderSource",
    "FrameSource",
    "RawFrame",
    "VideoSource",
    "open_source",
    "write_video",
]
