"""The frame sources of ``fringekit track``: folders, videos and cameras (a stand-in for
OpenCV's capture), the errors each can meet, and :func:`write_video`."""

from __future__ import annotations

import math
import sys
import threading
import time

import imageio.v3 as iio
import numpy as np
import png
import pytest

from fringekit.errors import InputError, SourceError
from fringekit.tracking import (
    CameraSource,
    FolderSource,
    VideoSource,
    open_source,
    write_video,
)


def one_line(excinfo, *parts: str) -> str:
    """The message of a raised error: one line, naming every part."""
    message = str(excinfo.value)
    assert "\n" not in message, message
    for part in parts:
        assert part in message, (part, message)
    return message


def gradient(rows: int, cols: int, k: int) -> np.ndarray:
    """A smooth RGB frame (h264 keeps it within a few levels), different for each k."""
    r, c = np.mgrid[:rows, :cols]
    img = np.stack([r * 4 + k * 10, c * 3, (r + c + k * 7) * 2], axis=2)
    return (img % 200 + 20).astype(np.uint8)


# --- folders ---------------------------------------------------------------------------


def test_a_folder_is_read_in_natural_order_with_times_from_fps(tmp_path):
    for k in (10, 2, 1):
        iio.imwrite(tmp_path / f"frame{k}.png", np.full((4, 6, 3), k, np.uint8))
    iio.imwrite(tmp_path / "FRAME11.TIF", np.full((4, 6, 3), 11, np.uint8))
    (tmp_path / "notes.txt").write_text("not a frame")
    (tmp_path / ".hidden.png").write_bytes(b"a file manager's shadow")
    with open_source(str(tmp_path), fps=4) as source:
        frames = list(source)
    assert isinstance(source, FolderSource)
    assert (source.kind, source.n_frames, source.fps, source.live, source.dropped) == (
        "folder",
        4,
        4.0,
        False,
        0,
    )
    assert [f.name for f in frames] == ["frame1.png", "frame2.png", "frame10.png", "FRAME11.TIF"]
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert [f.time_s for f in frames] == [0.0, 0.25, 0.5, 0.75]
    assert [int(f.image[0, 0, 0]) for f in frames] == [1, 2, 10, 11]
    # without a rate a folder's frames have no time; the folder can be read again
    assert all(math.isnan(f.time_s) for f in open_source(str(tmp_path)))


def write_png(path, image: np.ndarray) -> None:
    """A PNG of the image's depth (pypng: Pillow writes no 16-bit colour PNG)."""
    rows, cols = image.shape[:2]
    planes = image.shape[2] if image.ndim == 3 else 1
    writer = png.Writer(cols, rows, bitdepth=image.dtype.itemsize * 8, greyscale=planes == 1)
    with open(path, "wb") as fh:
        writer.write(fh, image.reshape(rows, cols * planes).tolist())


def test_a_folder_gives_pixels_as_stored_without_alpha(tmp_path):
    deep = np.arange(4 * 6 * 3, dtype=np.uint16).reshape(4, 6, 3) * 1000
    write_png(tmp_path / "a_deep.png", deep)
    (frame,) = open_source(str(tmp_path))
    assert frame.image.dtype == np.uint16 and np.array_equal(frame.image, deep)
    (tmp_path / "a_deep.png").unlink()
    rgba = np.zeros((4, 6, 4), np.uint8)
    rgba[..., 0], rgba[..., 3] = 90, 255
    iio.imwrite(tmp_path / "b_rgba.png", rgba)
    (frame,) = open_source(str(tmp_path))
    assert frame.image.shape == (4, 6, 3) and frame.image[0, 0].tolist() == [90, 0, 0]


@pytest.mark.parametrize(
    "odd, sizes",
    [
        (np.zeros((5, 6, 3), np.uint8), ("5 x 6 pixels", "4 x 6 pixels")),
        (np.zeros((4, 6), np.uint8), ("grey", "RGB")),
        (np.zeros((4, 6, 3), np.uint16), ("16-bit", "8-bit")),
    ],
    ids=["size", "channels", "depth"],
)
def test_a_frame_unlike_the_first_raises_at_that_frame(tmp_path, odd, sizes):
    for k in (1, 2, 4):
        iio.imwrite(tmp_path / f"f{k}.png", np.zeros((4, 6, 3), np.uint8))
    write_png(tmp_path / "f3.png", odd)
    taken = []
    with pytest.raises(SourceError) as excinfo:
        for frame in open_source(str(tmp_path)):
            taken.append(frame.name)
    assert taken == ["f1.png", "f2.png"]  # the caller keeps what it made of these
    one_line(excinfo, f"SOURCE {tmp_path}", "frame 2 (f3.png)", "f1.png", *sizes)


def test_an_unreadable_file_raises_at_its_frame(tmp_path):
    iio.imwrite(tmp_path / "f1.png", np.zeros((4, 6), np.uint8))
    (tmp_path / "f2.png").write_bytes(b"\x89PNG but then nothing")
    iio.imwrite(tmp_path / "f3.png", np.zeros((4, 6), np.uint8))
    taken = []
    with pytest.raises(SourceError) as excinfo:
        for frame in open_source(str(tmp_path)):
            taken.append(frame.index)
    assert taken == [0]
    one_line(excinfo, f"SOURCE {tmp_path}: frame 1", "f2.png", "not a readable")
    assert "PyAV" not in str(excinfo.value)  # imageio does not try an image as a video


def test_a_closed_source_yields_no_more_frames(tmp_path):
    for k in range(3):
        iio.imwrite(tmp_path / f"f{k}.png", np.zeros((4, 6), np.uint8))
    path = write_video(tmp_path / "clip.mkv", [np.zeros((4, 6, 3), np.uint8)] * 5, 5, lossless=True)
    for spec in (tmp_path, path):
        source = open_source(str(spec))
        frames = iter(source)
        assert next(frames).index == 0
        source.close()
        assert list(frames) == [] and list(source) == []


# --- videos ----------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".mkv", ".avi"])
def test_a_lossless_video_reads_back_pixel_for_pixel(tmp_path, suffix):
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 256, (31, 47, 3), dtype=np.uint8) for _ in range(6)]
    frames.append(rng.integers(0, 256, (31, 47), dtype=np.uint8))  # grey: written as RGB
    path = write_video(tmp_path / f"clip{suffix}", iter(frames), 7.5, lossless=True)
    with open_source(str(path)) as source:
        back = list(source)
    assert isinstance(source, VideoSource) and source.kind == "video" and source.fps == 7.5
    assert source.n_frames in (None, 7)  # Matroska states no count
    assert len(back) == 7
    assert all(np.array_equal(f.image, a) for f, a in zip(back[:6], frames[:6], strict=False))
    assert np.array_equal(back[6].image, np.repeat(frames[6][..., None], 3, axis=2))
    assert [f.name for f in back[:2]] == [f"clip{suffix}#0", f"clip{suffix}#1"]
    # presentation times, to the container's clock (Matroska counts milliseconds)
    assert np.allclose([f.time_s for f in back], np.arange(7) / 7.5, rtol=0, atol=1e-3)
    # fps replaces the video's own rate
    assert [f.time_s for f in open_source(str(path), fps=2)][:3] == [0.0, 0.5, 1.0]


def test_a_lossy_mp4_keeps_every_frame_and_evens_the_size(tmp_path):
    frames = [gradient(15, 22, k) for k in range(5)]
    path = write_video(tmp_path / "overlay.mp4", frames, 25)
    with open_source(str(path)) as source:
        back = list(source)
    assert source.n_frames == 5 and len(back) == 5 and source.fps == 25.0
    assert back[0].image.shape == (16, 22, 3) and back[0].image.dtype == np.uint8
    error = [np.abs(f.image[:15].astype(int) - a).mean() for f, a in zip(back, frames, strict=True)]
    assert max(error) < 4, error
    assert np.allclose([f.time_s for f in back], np.arange(5) / 25)


@pytest.mark.parametrize("content", [b"", b"not a video at all " * 50], ids=["empty", "garbage"])
def test_a_video_that_does_not_open_is_one_line(tmp_path, content):
    path = tmp_path / "broken.mp4"
    path.write_bytes(content)
    with pytest.raises(SourceError) as excinfo:
        open_source(str(path))
    one_line(excinfo, f"SOURCE {path}", "not a readable video", "camera:N")


def test_write_video_refuses_what_it_cannot_write(tmp_path):
    frame = np.zeros((4, 6, 3), np.uint8)
    with pytest.raises(InputError) as excinfo:
        write_video(tmp_path / "exact.mp4", [frame], 10, lossless=True)
    one_line(excinfo, "exact.mp4", ".mkv .avi")
    with pytest.raises(InputError) as excinfo:
        write_video(tmp_path / "none.mp4", [], 10)
    one_line(excinfo, "none.mp4", "no frame")
    with pytest.raises(InputError) as excinfo:
        write_video(tmp_path / "deep.mp4", [frame.astype(np.uint16)], 10)
    one_line(excinfo, "frame 0", "uint16", "uint8")
    with pytest.raises(InputError) as excinfo:
        write_video(tmp_path / "rate.mp4", [frame], 0)
    one_line(excinfo, "fps 0", "> 0")
    assert not list(tmp_path.iterdir())  # nothing was written
    # a frame of another size stops the video; the frames before it are kept
    with pytest.raises(InputError) as excinfo:
        write_video(tmp_path / "cut.mkv", [frame, frame, frame[:2]], 10, lossless=True)
    one_line(excinfo, "frame 2", "2 x 6", "4 x 6")
    assert len(list(open_source(str(tmp_path / "cut.mkv")))) == 2


# --- specs -----------------------------------------------------------------------------


def bad_specs(tmp_path):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("no image here")
    (tmp_path / "anim.gif").write_bytes(b"GIF89a")
    return {
        "camera:abc": ("camera:abc", "camera:N"),
        "camera:-1": ("camera:-1", "camera:N"),
        str(tmp_path / "missing"): ("missing does not exist", "a folder of images"),
        str(tmp_path / "missing.mp4"): ("missing.mp4 does not exist", "camera:N"),
        str(tmp_path / "empty"): ("holds no image file", ".png .tif .tiff .jpg .jpeg"),
        str(tmp_path / "anim.gif"): ("anim.gif is not allowed", "a .gif file", ".mp4 .avi"),
    }


def test_a_source_of_no_kind_is_one_line(tmp_path):
    for spec, parts in bad_specs(tmp_path).items():
        with pytest.raises(SourceError) as excinfo:
            open_source(spec)
        one_line(excinfo, f"SOURCE {spec}", *parts)


@pytest.mark.parametrize("fps", [0, -2, math.nan, "fast", True])
def test_an_fps_that_is_not_a_rate_is_one_line(tmp_path, fps):
    iio.imwrite(tmp_path / "f.png", np.zeros((4, 6), np.uint8))
    with pytest.raises(SourceError) as excinfo:
        open_source(str(tmp_path), fps=fps)
    one_line(excinfo, f"--fps {fps}", "> 0")


# --- cameras ---------------------------------------------------------------------------


class Capture:
    """A stand-in for ``cv2.VideoCapture``: frames 0..n-1 (BGR, the frame number in the
    first pixel), then a failed read. With ``gated`` each read waits for the test to let
    a frame through (:meth:`let`), so the test knows which frames exist when it asks."""

    def __init__(self, n: int, *, gated: bool = False, opened: bool = True, fps: float = 30.0):
        self.n, self.gated, self.opened, self.fps = n, gated, opened, fps
        self.reads = self.calls = self.let_through = 0
        self.released = False
        self.gate = threading.Semaphore(0)
        self.changed = threading.Condition()

    def isOpened(self):  # noqa: N802 (OpenCV's name)
        return self.opened

    def get(self, prop):
        return self.fps if prop == 5 else 0.0

    def release(self):
        self.released = True

    def read(self):
        with self.changed:
            self.calls += 1
            self.changed.notify_all()
        if self.reads >= self.n:
            return False, None
        if self.gated:
            self.gate.acquire()
        self.reads += 1
        bgr = np.zeros((4, 6, 3), np.uint8)
        bgr[0, 0] = (self.reads - 1) % 256, 1, 2  # B, G, R
        return True, bgr

    def let(self, k: int) -> None:
        """Let k more frames be read, and wait until the reading thread has called
        ``read`` once more after the last of them (so that frame is in the source's
        slot)."""
        self.let_through += k
        target = min(self.let_through, self.n) + 1
        for _ in range(k):
            self.gate.release()
        with self.changed:
            assert self.changed.wait_for(lambda: self.calls >= target, 10)


def camera_threads(number: int) -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == f"fringekit-camera-{number}"]


def test_camera_frames_arrive_in_rgb_with_the_grab_counter(monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # the factory is used: OpenCV never is
    capture = Capture(5)
    with open_source("camera:2", capture_factory=lambda n: capture) as camera:
        assert isinstance(camera, CameraSource)
        assert (camera.kind, camera.live, camera.n_frames, camera.fps) == (
            "camera",
            True,
            None,
            30.0,
        )
        frames = list(camera)
    indices = [f.index for f in frames]
    assert indices == sorted(set(indices)) and indices[-1] == 4  # the last frame is yielded
    assert len(frames) + camera.dropped == 5
    assert frames[-1].name == "camera:2#4"
    assert frames[-1].image[0, 0].tolist() == [2, 1, 4]  # R, G, B of the BGR pixel
    times = [f.time_s for f in frames]
    assert times == sorted(times) and times[0] >= 0
    assert capture.released and not camera_threads(2)


def test_a_slow_consumer_gets_the_newest_frame_and_the_rest_are_dropped():
    capture = Capture(210, gated=True)
    camera = open_source("camera:1", capture_factory=lambda n: capture)
    frames = iter(camera)
    taken = []
    for k in (1, 3, 4, 200):  # frames read between two takes
        if k == 1:  # the first take starts the reading thread
            threading.Timer(0.05, capture.let, (1,)).start()
        else:
            capture.let(k)
        taken.append(next(frames).index)
    assert taken == [0, 3, 7, 207]
    assert camera.dropped == 208 - 4  # the slot held one frame: the others were replaced
    capture.let(2)  # frames 208 and 209, then the camera fails to read
    assert [f.index for f in frames] == [209]  # what the slot holds, then the end
    assert capture.reads == 210 and camera.dropped == 210 - 5
    camera.close()
    assert capture.released and not camera_threads(1)


def test_close_stops_the_reading_thread_and_releases_the_camera():
    capture = Capture(10**9)
    camera = open_source("camera:7", capture_factory=lambda n: capture)
    frames = iter(camera)
    taken = [next(frames) for _ in range(3)]
    assert camera_threads(7)
    camera.close()
    assert not camera_threads(7) and capture.released
    reads = capture.reads
    time.sleep(0.02)
    assert capture.reads == reads  # nothing reads any more
    assert list(frames) == []  # the stream has ended
    assert len(taken) + camera.dropped == reads
    # a camera closed before it was read is released without a thread
    unused = Capture(3)
    open_source("camera:8", capture_factory=lambda n: unused).close()
    assert unused.released and unused.calls == 0 and not camera_threads(8)


def test_a_camera_that_does_not_open_is_one_line():
    capture = Capture(3, opened=False)
    with pytest.raises(SourceError) as excinfo:
        open_source("camera:3", capture_factory=lambda n: capture)
    one_line(excinfo, "camera:3 did not open", "check the camera index", "folder or video")
    assert capture.released


def test_a_camera_without_opencv_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 raises ImportError
    with pytest.raises(SourceError) as excinfo:
        open_source("camera:0")
    one_line(excinfo, "SOURCE camera:0", "pip install opencv-python-headless")


def test_a_camera_takes_no_fps():
    with pytest.raises(SourceError) as excinfo:
        open_source("camera:0", fps=30, capture_factory=lambda n: Capture(1))
    one_line(excinfo, "--fps 30", "camera:0")
