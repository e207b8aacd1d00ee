"""``fringekit track --show``: the live window, in a process of its own.

The solver's loop only hands over what it solved: each frame's record (time, ids, loads)
and, at most every ``interval_s``, the newest frame, through a queue of one slot that it
never waits on. A second process (``spawn``: no copy of the solver's threads) paints the
overlay, draws the rolling loads and runs the window's event loop. So the solver neither
paints nor draws nor contends with the drawing for Python's interpreter lock, and a
window that falls behind skips display updates, never data frames: the records of the
frames it did not draw ride with the next frame it is sent, and the rolling plot holds
every frame solved.
"""

from __future__ import annotations

import multiprocessing
import os
import pkgutil
import queue
import signal
import threading
import time
from collections import deque
from contextlib import contextmanager

import numpy as np
from matplotlib.backends import BackendFilter, backend_registry
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from fringekit.tracking.figure import OverlayPainter, sheet_to_pixel

__all__ = [
    "DEFAULT_WINDOW",
    "LiveDisplay",
    "LoadsView",
    "MatplotlibWindow",
    "NoWindowError",
    "OffscreenWindow",
    "marks",
    "rolling_loads",
]

#: The window the display process opens: "module:class", made there with no argument;
#: the class has ``draw(rgb, loads)``, ``wait(seconds)`` (its event loop) and ``is_open()``.
DEFAULT_WINDOW = "fringekit.tracking.display:MatplotlibWindow"

#: How long the display process runs the window's event loop between two looks at its
#: queue (s): the window stays responsive, a frame waits at most this long to be drawn.
IDLE_S = 0.02

#: The display process's niceness (POSIX): where the cores are busy solving, it gets
#: little more than their idle time. On the track bench (mono, 2-thread solver, 2 cores)
#: with the window drawn off-screen: 5.1-5.2 frames a second without it, 2.2 with the
#: drawing in the solver's loop (about 250 ms a redraw); in its process, 3.4 un-niced,
#: 4.1-4.7 at niceness 10 (21-28 redraws in 43-49 s) and 4.7 at 19 (12 redraws) while
#: BLAS ran 2 threads in the solver; 5.07 at niceness 10 (84 redraws in 39 s) with one.
NICE = 10

#: How long the end of a run waits for the window to draw the last records and close (s).
CLOSE_S = 10.0


class LiveDisplay:
    """The ``--show`` window in its own process, fed as an ``on_frame`` callback.

    Parameters
    ----------
    pixel_mm : float
        The frames' pixel pitch on the sheet (mm), for the overlay.
    origin_px : (row, col) or None
        The frames' pixel of the sensor origin (None: the image centre).
    window : str
        "module:class" of the window the display process makes (:data:`DEFAULT_WINDOW`);
        the module must be importable there.
    interval_s : float
        The least time between two frames sent to the window (s): 5 redraws a second by
        default.
    history : int
        Frames the rolling plot holds (the oldest are dropped: bounded memory on both
        sides).
    clock : callable
        Seconds (a test's fake clock).

    Notes
    -----
    Use it as a context manager, or call :meth:`close`: it sends the last records, ends
    the process and says why the window failed, if it did (no display, a closed window is
    not a failure). The process is started by ``spawn``, which imports the script that
    made it: a script must keep its work under ``if __name__ == "__main__":``.

    Examples
    --------
    A window that records what it is sent (defined in a module the new process imports),
    fed three frames at once (a clock standing still): the first is sent, the other two
    come within the 0.2 s interval and are not, yet their records reach the window when
    it closes.

    >>> import sys, tempfile, textwrap
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> _ = (folder / "recording_window.py").write_text(textwrap.dedent('''
    ...     import json, time
    ...     from pathlib import Path
    ...     class Window:
    ...         def __init__(self): self.log = Path(__file__).with_name("drawn.json")
    ...         def is_open(self): return True
    ...         def wait(self, seconds): time.sleep(seconds)
    ...         def draw(self, rgb, loads):
    ...             rows = {str(i): fz.tolist() for i, (t, fz, ft) in loads.items()}
    ...             self.log.write_text(json.dumps([rgb.shape, rows]))
    ... '''))
    >>> sys.path.insert(0, str(folder))
    >>> from fringekit.tracking.frame import TrackedFrame
    >>> def frame(k):
    ...     params = np.array([[0.0, 0.0, 2.0 + k, 0.0, 0.0]])
    ...     return TrackedFrame(k, 0.1 * k, np.array([1]), params, np.zeros((1, 5)),
    ...                         np.zeros(1), np.ones(1, bool))
    >>> window = "recording_window:Window"
    >>> with LiveDisplay(0.25, None, window=window, clock=lambda: 0.0) as view:
    ...     for k in range(3):
    ...         view(frame(k), np.zeros((8, 8), np.uint8))
    >>> view.error, view.sent, view.skipped
    (None, 1, 2)
    >>> (folder / "drawn.json").read_text()
    '[[8, 8, 3], {"1": [2.0, 3.0, 4.0]}]'
    >>> sys.path.remove(str(folder))
    """

    def __init__(
        self,
        pixel_mm: float,
        origin_px,
        *,
        window: str = DEFAULT_WINDOW,
        interval_s: float = 0.2,
        history: int = 500,
        clock=time.monotonic,
    ):
        ctx = multiprocessing.get_context("spawn")
        self.inbox, self.outbox = ctx.Queue(maxsize=1), ctx.Queue()
        self.process = ctx.Process(
            target=_serve,
            args=(self.inbox, self.outbox, window, pixel_mm, origin_px, int(history)),
            name="fringekit-show",
            daemon=True,
        )
        with _sigint_ignored():  # a Ctrl-C while it starts is the solver's, not its
            self.process.start()
        self.interval, self.clock = float(interval_s), clock
        self.pending: deque = deque(maxlen=int(history))
        self.newest = None
        self.last = -float("inf")
        self.sent = self.skipped = 0
        self.error: str | None = None
        self.closed = False

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __call__(self, frame, image) -> None:
        """Take one solved frame (None: left out) and its image; never waits."""
        if frame is not None:
            self.pending.append((frame.time_s, tuple(int(i) for i in frame.ids), frame.params))
        self.newest = (marks(frame), image)
        now = self.clock()
        if now - self.last < self.interval or not self._send():
            self.skipped += 1
            return
        self.last = now
        self.sent += 1

    def _send(self, deadline: float | None = None) -> bool:
        """Hand the newest frame with the records since the last one sent to the window
        (False: its slot is still full, by ``deadline`` (time.monotonic) when given, or
        its process has ended)."""
        if self.newest is None:
            return False
        (params, ids), image = self.newest
        item = ((np.asarray(params), tuple(ids)), np.asarray(image), list(self.pending))
        if not self._put(item, deadline):
            return False
        self.pending.clear()
        return True

    def _put(self, item, deadline: float | None) -> bool:
        """Put ``item`` in the window's slot, waiting until ``deadline`` at most (None:
        not at all) and no longer than the window's process lives."""
        while self.process.is_alive():
            try:
                self.inbox.put_nowait(item)
                return True
            except queue.Full:
                if deadline is None or time.monotonic() > deadline:
                    return False
                time.sleep(0.01)
        return False

    def close(self) -> str | None:
        """Send the last records, end the window's process, and return why the window
        failed (None when it did not: it drew, or was closed by its user). It waits
        CLOSE_S at most, and a Ctrl-C while it waits ends the window at once."""
        if self.closed:
            return self.error
        self.closed = True
        deadline = time.monotonic() + CLOSE_S
        unsent = 0
        try:
            if self.pending and not self._send(deadline):
                unsent = len(self.pending)
            if self._put(None, deadline):
                self.process.join(max(0.0, deadline - time.monotonic()))
        except KeyboardInterrupt:
            pass  # the run's own Ctrl-C handling goes on: the window is ended below
        stuck = self.process.is_alive()
        if stuck:
            self.process.terminate()
            self.process.join()
        try:
            self.error = self.outbox.get(timeout=1.0)
        except queue.Empty:
            self.error = (
                f"it did not close within {CLOSE_S:g} s and was ended"
                if stuck
                else f"its process ended with exit code {self.process.exitcode}, its error "
                "printed above"
            )
        if self.error is None and unsent:
            self.error = f"it did not take the last {unsent} frame(s)' loads"
        # what the process did not read is dropped: exit must not wait on writing it
        self.inbox.cancel_join_thread()
        self.inbox.close()
        self.outbox.close()
        return self.error


@contextmanager
def _sigint_ignored():
    """SIGINT ignored inside the block (in the main thread; elsewhere as it is): a process
    started in it inherits the disposition, and Python keeps it ignored as it starts."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def _serve(inbox, outbox, window: str, pixel_mm: float, origin_px, history: int) -> None:
    """The display process: draw what comes until ``None``; put None (it drew, or its
    user closed the window) or why it failed on ``outbox``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the solver's: it ends the run
    if hasattr(os, "nice"):  # the solver's cores first: the window draws in their idle time
        os.nice(NICE)
    try:
        win = pkgutil.resolve_name(window)()
        kept: deque = deque(maxlen=history)
        painter = None
        while True:
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                if not win.is_open():
                    break
                win.wait(IDLE_S)
                continue
            if item is None:
                break
            (params, ids), image, records = item
            kept.extend(records)
            if painter is None:
                shape = image.shape[:2]
                painter = OverlayPainter(shape, sheet_to_pixel(shape, pixel_mm, origin_px))
            win.draw(painter.paint(image, params, ids), rolling_loads(kept))
    except NoWindowError as exc:
        outbox.put(str(exc))
        return
    except Exception as exc:  # reported to the run, which goes on without its window
        outbox.put(f"{type(exc).__name__}: {exc}")
        return
    outbox.put(None)


class NoWindowError(RuntimeError):
    """matplotlib can open no window here."""


class MatplotlibWindow:
    """The ``--show`` window (:class:`LoadsView` in a matplotlib figure on screen).

    Raises
    ------
    NoWindowError
        Where matplotlib's backend is a file backend (no display, or ``MPLBACKEND`` set to
        one), which would open no window.
    """

    def __init__(self):
        import matplotlib.pyplot as plt  # lazy: a GUI backend only when a window is asked

        backend = plt.get_backend()
        if backend.lower() in backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE):
            raise NoWindowError(
                f"matplotlib's backend is {backend}, which opens no window (no display, "
                "or MPLBACKEND names a file backend)"
            )
        self.plt = plt
        self.fig = plt.figure(figsize=(10, 4.5))
        self.view = LoadsView(self.fig)
        plt.show(block=False)

    def is_open(self) -> bool:
        return self.plt.fignum_exists(self.fig.number)

    def wait(self, seconds: float) -> None:
        """Run the window's event loop for ``seconds`` (s)."""
        self.fig.canvas.start_event_loop(seconds)

    def draw(self, rgb: np.ndarray, loads: dict) -> None:
        """Show ``rgb`` and ``loads`` (:meth:`LoadsView.draw`)."""
        self.view.draw(rgb, loads)
        self.fig.canvas.draw_idle()


class OffscreenWindow:
    """The ``--show`` window's drawing done in full into an image in memory, with nothing
    on screen (``window="fringekit.tracking.display:OffscreenWindow"``): what the window
    costs, measured where there is no display (``bench/track.py --show``).

    Examples
    --------
    >>> import numpy as np
    >>> w = OffscreenWindow()
    >>> w.draw(np.zeros((4, 6, 3), np.uint8), {})
    >>> w.draws, w.is_open()
    (1, True)
    """

    def __init__(self):
        self.fig = Figure(figsize=(10, 4.5))
        self.canvas = FigureCanvasAgg(self.fig)
        self.view = LoadsView(self.fig)
        self.draws = 0

    def is_open(self) -> bool:
        return True

    def wait(self, seconds: float) -> None:
        time.sleep(seconds)

    def draw(self, rgb: np.ndarray, loads: dict) -> None:
        self.view.draw(rgb, loads)
        self.canvas.draw()
        self.draws += 1


class LoadsView:
    """What the ``--show`` window holds, in a matplotlib figure: the newest frame with its
    overlay beside a rolling plot of each contact's Fz (solid) and tangential load
    (dashed), one colour per id.

    Examples
    --------
    >>> import numpy as np
    >>> from matplotlib.figure import Figure
    >>> view = LoadsView(Figure())
    >>> loads = {3: (np.r_[0.0, 0.1], np.r_[1.0, 2.0], np.r_[0.0, 0.5])}  # t, Fz, Ft
    >>> view.draw(np.zeros((4, 6, 3), np.uint8), loads)
    >>> view.ax.images[0].get_array().shape
    (4, 6, 3)
    >>> [line.get_ydata().tolist() for line in view.ax_load.lines]  # Fz, then tangential
    [[1.0, 2.0], [0.0, 0.5]]
    """

    def __init__(self, fig):
        self.ax, self.ax_load = fig.subplots(1, 2)
        self.ax.set_axis_off()
        self.image = None

    def draw(self, rgb: np.ndarray, loads: dict) -> None:
        """Show ``rgb`` (rows, cols, 3) uint8 and ``loads`` (:func:`rolling_loads`)."""
        if self.image is None:
            self.image = self.ax.imshow(rgb)
        else:
            self.image.set_data(rgb)
        ax = self.ax_load
        ax.clear()
        for i, (t, fz, ft) in sorted(loads.items()):  # a handful of contacts
            colour = f"C{i % 10}"
            ax.plot(t, fz, color=colour, label=f"{i}")
            ax.plot(t, ft, color=colour, linestyle="--")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("Fz (solid), tangential (dashed) (N)")
        if loads:
            ax.legend(title="id", loc="upper left", fontsize="small")


def rolling_loads(history) -> dict:
    """Each contact's loads through ``history``, a sequence of (time_s, ids (n,), params
    (n, 5)) as :class:`LiveDisplay` sends them: {id: (time (k,) s, Fz (k,) N, tangential
    magnitude (k,) N)}, in the order of the frames.

    Examples
    --------
    >>> import numpy as np
    >>> h = [(0.0, (1,), np.array([[0, 0, 2.0, 0.3, 0.4]])),
    ...      (0.1, (1, 2), np.array([[0, 0, 2.5, 0.6, 0.8], [3, 3, 1.0, 0, 0]]))]
    >>> loads = rolling_loads(h)
    >>> sorted(loads), loads[1][1].tolist(), loads[1][2].tolist(), loads[2][0].tolist()
    ([1, 2], [2.0, 2.5], [0.5, 1.0], [0.1])
    """
    rows: dict = {}
    for t, ids, params in history:  # a few hundred frames of a handful of contacts
        p = np.reshape(params, (-1, 5))
        for i, (fz, fx, fy) in zip(ids, p[:, 2:], strict=True):
            rows.setdefault(i, []).append((t, fz, float(np.hypot(fx, fy))))
    return {i: tuple(np.array(col) for col in zip(*r, strict=True)) for i, r in rows.items()}


def marks(frame) -> tuple[np.ndarray, tuple]:
    """The overlay's (params (n, 5), ids) of a tracked frame; none for a frame left out
    (None: the library could not explain it).

    Examples
    --------
    >>> params, ids = marks(None)
    >>> params.shape, ids
    ((0, 5), ())
    """
    if frame is None:
        return np.zeros((0, 5)), ()
    return frame.params, tuple(frame.ids)
