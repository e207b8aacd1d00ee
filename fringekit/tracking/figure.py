"""The figures of ``fringekit track``: ``loads.png`` (each contact's loads against time)
and the overlay of a frame (an arrow per contact for its tangential load, its id and Fz),
for ``track.mp4`` and the live view."""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ["OverlayPainter", "loads_figure", "sheet_to_pixel"]


def loads_figure(path, table: dict) -> None:
    """Each contact's Fz and tangential load |(Fx, Fy)| (N) against time (s; the frame
    number when the stream has no clock), with the 1-sigma band, one colour per id."""
    fig = Figure(figsize=(8, 5.5), dpi=100)
    ax_n, ax_t = fig.subplots(2, 1, sharex=True)
    t = np.asarray(table["time_s"], float)
    clock = bool(len(t)) and bool(np.all(np.isfinite(t)))
    x = t if clock else np.asarray(table["frame"], float)
    ft = np.hypot(table["Fx_N"], table["Fy_N"])
    with np.errstate(invalid="ignore", divide="ignore"):
        sft = np.hypot(table["Fx_N"] * table["sFx_N"], table["Fy_N"] * table["sFy_N"]) / ft
    sft = np.where(np.isfinite(sft), sft, np.hypot(table["sFx_N"], table["sFy_N"]))
    for i in np.unique(table["id"]):  # contacts (a handful)
        m = table["id"] == i
        for ax, v, s in ((ax_n, table["Fz_N"], table["sFz_N"]), (ax_t, ft, sft)):
            (line,) = ax.plot(x[m], v[m], lw=1.2, label=f"contact {i}")
            ax.fill_between(x[m], v[m] - s[m], v[m] + s[m], color=line.get_color(), alpha=0.25)
    ax_n.set_ylabel("normal load Fz (N)")
    ax_t.set_ylabel("tangential load (N)")
    ax_t.set_xlabel("time (s)" if clock else "frame")
    if len(table["id"]):
        ax_n.legend(loc="best", fontsize=8)
    else:
        ax_n.set_title("no contact found in any frame")
    fig.suptitle("loads per contact (band: 1-sigma)")
    fig.tight_layout()
    fig.savefig(path)


class OverlayPainter:
    """Draws frames with an arrow per contact (its tangential load), its id and Fz, on one
    reused matplotlib figure (RGB arrays out, for a video or a window).

    Parameters
    ----------
    shape : (rows, cols)
        The frames' size (px).
    pixel_to_rc : callable
        (x_mm, y_mm) arrays -> (row, col) arrays.
    arrow_px_per_N : float
        Arrow length per newton of tangential load (px).

    Examples
    --------
    >>> import numpy as np
    >>> p = OverlayPainter((40, 60), lambda x, y: (20 - y, 30 + x))
    >>> p.paint(np.zeros((40, 60), np.uint8), np.array([[1.0, 2.0, 3.0, 0.5, 0.0]]), [7]).shape
    (40, 60, 3)
    """

    def __init__(self, shape, pixel_to_rc, arrow_px_per_N: float = 20.0):
        rows, cols = shape
        self.shape, self.to_rc, self.scale = (rows, cols), pixel_to_rc, arrow_px_per_N
        self.fig = Figure(figsize=(cols / 100, rows / 100), dpi=100)
        self.canvas = FigureCanvasAgg(self.fig)
        self.ax = self.fig.add_axes((0, 0, 1, 1))
        self.ax.set_axis_off()

    def paint(self, image: np.ndarray, params: np.ndarray, ids) -> np.ndarray:
        """The frame with its overlay, (rows, cols, 3) uint8; ``params`` (n, 5) x, y (mm),
        Fz, Fx, Fy (N) as :class:`~fringekit.tracking.frame.TrackedFrame` holds them."""
        ax = self.ax
        ax.clear()
        ax.set_axis_off()
        top = np.iinfo(image.dtype).max if image.dtype.kind in "ui" else 1.0
        ax.imshow(image / top, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        ax.set_xlim(-0.5, self.shape[1] - 0.5)
        ax.set_ylim(self.shape[0] - 0.5, -0.5)
        p = np.reshape(params, (-1, 5))
        r, c = self.to_rc(p[:, 0], p[:, 1])
        for k, i in enumerate(ids):  # contacts (a handful)
            ax.annotate(
                "",
                xy=(c[k] + self.scale * p[k, 3], r[k] - self.scale * p[k, 4]),
                xytext=(c[k], r[k]),
                arrowprops={"arrowstyle": "->", "color": "yellow", "lw": 1.5},
            )
            ax.text(c[k] + 4, r[k] - 4, f"{i}: {p[k, 2]:.2f} N", color="cyan", fontsize=7)
        self.canvas.draw()
        rgba = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[: self.shape[0], : self.shape[1], :3])


def sheet_to_pixel(shape, pixel_mm: float, origin_px):
    """(x_mm, y_mm) -> (row, col) on a frame of ``shape`` (rows, cols) px, whose pixel
    pitch on the sheet is ``pixel_mm`` (mm) and whose sensor origin is at the pixel
    ``origin_px`` (row, col; None: the image centre); x runs right, y up.

    Examples
    --------
    >>> to_rc = sheet_to_pixel((5, 7), 0.5, None)
    >>> to_rc(1.0, 0.5)
    (1.0, 5.0)
    """
    rows, cols = shape
    r0, c0 = origin_px if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
    return lambda x, y: (r0 - y / pixel_mm, c0 + x / pixel_mm)
