"""Does the image's fringe spacing fit the library's at ``--pixel-mm``? (``invert``, before
detection.)

A wrong pixel pitch makes every fringe the wrong size in mm: no load in the library's
range fits, and the fit searched for minutes before it gave up (a library image of the
coarse test sensor at 0.25 mm/px, inverted with ``--pixel-mm 2``: no answer after 120 s;
the right pitch takes 0.3 s).

The fringes' mean spatial frequency ``k`` (rad per pixel or per mm) is the image's RMS
gradient over its RMS deviation from its mean (``k`` of a sinusoid; over a pattern, its
frequency weighted by the fringes' energy), image noise taken out of both, on the usable
pixels whose neighbours are usable (a no-data disc's edge is not a fringe). It does not
depend on the camera's gain and offset or on dark or bright field. The library's ``k``
(rad/mm) is measured the same way on its one-indenter images at its smallest and largest
normal load, centred in the lattice's square at LIBRARY_PITCH_MM: the image's ``k``
(rad/px) over those gives the range of pitches the fringes suggest.

The measure is coarse, and biased one way: an image that crops an indenter's far field,
or holds several indenters, reads a higher ``k`` than one indenter centred in the
library's larger square (the far field and the mean weigh less). Library images of one
indenter at 0.25 mm/px read 0.23-0.34 mm/px; the FEM images of two sheared indenters of
tests/test_invert.py at 0.125 mm/px read 0.22-0.32 (grey), 0.19-0.29 (colour) and
0.19-0.27 (six steps). So a ``--pixel-mm`` is refused (:class:`~fringekit.inversion.verdict.
InvertError`) only when it is more than BELOW times under the range or ABOVE times over
it: the tests' images pass by a factor of 1.5 or more, a pitch 8 times too large or too
small is refused.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import ndimage

from fringekit.inversion.model import ImageModel
from fringekit.inversion.verdict import InvertError
from fringekit.library.store import LoadedIndenter
from fringekit.optics import PixelGrid

__all__ = ["ABOVE", "BELOW", "LIBRARY_PITCH_MM", "check_scale", "fringe_frequency"]

#: A ``--pixel-mm`` this factor below the smallest pitch the fringes suggest, or ABOVE
#: times above the largest, is refused (module docstring: the measure reads high).
BELOW = 4.0
ABOVE = 2.0
#: The pitch (mm) of the library images whose fringe frequency is measured (the
#: lattice's radial step is 0.1 mm near the axis; at 0.1 mm they read within 6 %).
LIBRARY_PITCH_MM = 0.05
#: An image whose fringe variance is below this many noise variances has no fringes to
#: measure (the check is skipped: detection finds nothing there either).
MIN_CONTRAST = 25.0


def fringe_frequency(image: np.ndarray, usable: np.ndarray, noise: float = 0.0) -> float | None:
    """The fringes' mean spatial frequency (rad/px) of an image (rows, cols, C) on its
    ``usable`` pixels (rows, cols), noise of sd ``noise`` taken out; None without fringes.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.inversion.scale import fringe_frequency
    >>> c = np.arange(200.0)
    >>> img = np.tile(0.5 + 0.4 * np.sin(0.3 * c), (50, 1))[..., None]
    >>> round(fringe_frequency(img, np.ones((50, 200), bool)), 2)  # central differences
    0.29
    """
    inner = ndimage.binary_erosion(usable, iterations=2, border_value=0)
    n = np.count_nonzero(inner)
    if n < 16:
        return None
    grad = var = 0.0
    for c in range(image.shape[-1]):  # channels (1, 3 or 6)
        gy, gx = np.gradient(image[..., c])
        grad += float(np.sum(gx[inner] ** 2 + gy[inner] ** 2)) / n - noise**2
        var += float(np.var(image[..., c][inner])) - noise**2
    if var <= MIN_CONTRAST * noise**2 * image.shape[-1] or grad <= 0:
        return None
    return float(np.sqrt(grad / var))


def _library_frequency(model: ImageModel, load_N: float) -> float | None:
    """The fringe frequency (rad/mm) of the library's image of one indenter at ``load_N``
    (no tangential load, the first diameter), centred on a grid of LIBRARY_PITCH_MM out to
    the library's lattice radius."""
    lib = model.lib
    n = int(2 * lib.lattice.r_max * 1e3 / LIBRARY_PITCH_MM)
    grid = PixelGrid((n, n), LIBRARY_PITCH_MM * 1e-3, (0.0, 0.0))
    blank = replace(
        model, grid=grid, points=None, keep=None, inner=0.0, exact=False, residual_ab=None
    )
    d = lib.diameters_mm[0] * 1e-3
    img, outside = blank.linear([LoadedIndenter(0.0, 0.0, d, 0.0, 0.0, float(load_N))])
    k = fringe_frequency(img.reshape(n, n, -1), outside.reshape(n, n))
    return None if k is None else k / LIBRARY_PITCH_MM


def check_scale(model: ImageModel, pixel_mm: float, noise: float) -> dict | None:
    """Refuse a ``pixel_mm`` the fringes contradict (module docstring); return what was
    measured (the image's frequency and the pitch range the fringes suggest) or None when
    there are no fringes to measure.

    Raises
    ------
    InvertError
        A ``pixel_mm`` more than BELOW times under or ABOVE times over the range the
        fringes suggest.
    """
    rows, cols = model.grid.shape
    k_img = fringe_frequency(
        model.measured.reshape(rows, cols, -1), model.usable.reshape(rows, cols), noise
    )
    lib = model.lib
    k_lib = [_library_frequency(model, f) for f in (lib.load_N[1], lib.max_load_N)]
    if k_img is None or None in k_lib:
        return None
    lo, hi = sorted(k_img / k for k in k_lib)  # mm/px
    found = {"image_rad_per_px": k_img, "pixel_mm_range": [lo, hi]}
    if lo / BELOW <= pixel_mm <= hi * ABOVE:
        return found
    raise InvertError(
        f"--pixel-mm {pixel_mm:g} contradicts the fringes: they are {2 * np.pi / k_img:.3g} "
        f"px apart, which the library's loads ({lib.load_N[1]:g}-{lib.max_load_N:g} N) make "
        f"at about {lo:.3g}-{hi:.3g} mm per pixel; give the pixel pitch on the sheet (mm)"
    )
