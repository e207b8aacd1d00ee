"""Which colour channel of a photograph carries the fringes of monochromatic light.

A colour camera behind a polariscope lit by one wavelength (a sodium lamp, a green LED)
records one fringe pattern in every channel, each with its own gain; white light's
isochromatics make each channel's fringe spacing scale with its wavelength instead, so
the channels decorrelate as the order grows (the basis of RGB photoelasticity: Ajovalasit,
Barone and Petrucci, "Towards RGB photoelasticity", Experimental Mechanics 35, 1995).
These functions tell the two apart and pick the channel a monochrome analysis reads.
"""

from __future__ import annotations

import numpy as np

from .images import image_noise_sd

__all__ = [
    "AGREE_MIN",
    "FLAT_NOISE",
    "brightest_channel",
    "channel_agreement",
    "featureless",
    "grey_channel",
    "strongest_channel",
]

#: A colour photograph is one of monochromatic light when its channels agree to this
#: correlation (channels with at least AGREE_SPREAD of the widest one's 1-99 % range); white
#: light's isochromatics decorrelate the channels beyond about half an order.
AGREE_MIN = 0.9
AGREE_SPREAD = 0.2
#: A colour photograph shows no light pattern when every channel's 1-99 % range is within
#: this many times that channel's noise sd (Gaussian noise alone spans 4.65 sd): its
#: channels are each their own noise, and their disagreement says nothing of the light.
FLAT_NOISE = 8.0


def channel_agreement(image: np.ndarray, mask: np.ndarray | None = None) -> tuple[float, str]:
    """How far a colour photograph's channels are copies of one fringe pattern.

    The least Pearson correlation between two channels over ``mask``, among the channels
    whose 1-99 % range is at least :data:`AGREE_SPREAD` of the widest one's (a weak
    channel of green light carries mostly noise). Monochromatic light makes every channel
    the same fringe pattern up to a gain, so the correlation is near 1; white light's
    isochromatics make each channel's fringe spacing scale with its wavelength, so the
    channels drift apart as the order grows.

    Parameters
    ----------
    image : (rows, cols, 3) float array
        A colour photograph.
    mask : (rows, cols) bool array, optional
        Pixels that decide (default all).

    Returns
    -------
    correlation : float
        In [-1, 1]; 1 for a grey image or a single strong channel.
    pair : str
        The least-agreeing channel pair (``"red-blue"``), ``""`` when none.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import channel_agreement
    >>> order = np.linspace(0, 4, 200)[None, :] * np.ones((8, 1))  # 0-4 fringes, 550 nm
    >>> lam = np.array([620.0, 550.0, 460.0])  # nm, the channels' effective wavelengths
    >>> white = np.sin(np.pi * order[..., None] * 550 / lam) ** 2
    >>> c, pair = channel_agreement(white)
    >>> bool(c < 0.5), pair
    (True, 'green-blue')
    >>> sodium = np.sin(np.pi * order[..., None]) ** 2 * np.array([0.8, 1.0, 0.3])
    >>> round(channel_agreement(sodium)[0], 3)
    1.0
    """
    img = np.asarray(image, float)
    if img.ndim == 2:
        return 1.0, ""
    m = np.ones(img.shape[:2], bool) if mask is None else mask
    px = img[m & np.all(np.isfinite(img), axis=-1)]
    if len(px) < 3:
        return 1.0, ""
    spread = np.subtract(*np.percentile(px, [99, 1], axis=0))
    strong = np.flatnonzero(spread >= AGREE_SPREAD * spread.max())
    if len(strong) < 2 or spread.max() <= 0:
        return 1.0, ""
    corr = np.corrcoef(px[:, strong].T)
    i, j = np.unravel_index(np.argmin(corr), corr.shape)
    names = ("red", "green", "blue")
    return float(corr[i, j]), f"{names[strong[min(i, j)]]}-{names[strong[max(i, j)]]}"


def grey_channel(image: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """A colour photograph of monochromatic light as one channel.

    Parameters
    ----------
    image : (rows, cols) or (rows, cols, 3) float array
    mask : (rows, cols) bool array, optional
        Pixels that decide.

    Returns
    -------
    (rows, cols) float array
        The image itself when grey, else the channel with the widest 1-99 % range in
        ``mask`` (green light on a colour camera: green).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import grey_channel
    >>> fringes = np.sin(np.linspace(0, 6, 20))[None, :] ** 2 * np.ones((4, 1))
    >>> green_light = np.stack([0.1 * fringes, fringes, 0.2 * fringes], axis=-1)
    >>> bool((grey_channel(green_light) == fringes).all())
    True
    """
    img = np.asarray(image, float)
    return img if img.ndim == 2 else img[..., strongest_channel(img, mask)]


def strongest_channel(image: np.ndarray, mask: np.ndarray | None = None) -> int:
    """The channel of a colour photograph with the widest 1-99 % range: the one
    :func:`grey_channel` reads.

    Parameters
    ----------
    image : (rows, cols, 3) float array
    mask : (rows, cols) bool array, optional
        Pixels that decide (default all).

    Returns
    -------
    int
        0, 1 or 2 (red, green, blue).

    Examples
    --------
    >>> import numpy as np
    >>> fringes = np.sin(np.linspace(0, 6, 20))[None, :] ** 2 * np.ones((4, 1))
    >>> strongest_channel(np.stack([0.1 * fringes, fringes, 0.2 * fringes], axis=-1))
    1
    """
    img = np.asarray(image, float)
    m = np.ones(img.shape[:2], bool) if mask is None else mask
    spread = [np.subtract(*np.percentile(img[..., k][m], [99, 1])) for k in range(3)]
    return int(np.argmax(spread))


def featureless(image: np.ndarray, mask: np.ndarray | None = None) -> bool:
    """Whether a colour photograph shows no light pattern: every channel's 1-99 % range
    within :data:`FLAT_NOISE` times its own noise sd (:func:`image_noise_sd`). A dark-field
    sensor at rest in even light is such a frame: :func:`channel_agreement` would find its
    channels uncorrelated, as white light's, though they only hold noise.

    Parameters
    ----------
    image : (rows, cols, 3) float array
    mask : (rows, cols) bool array, optional
        Pixels that decide (default all).

    Returns
    -------
    bool

    Examples
    --------
    >>> import numpy as np
    >>> noise = np.random.default_rng(0).normal(0.02, 0.002, (64, 64, 3))
    >>> featureless(noise)
    True
    >>> glare = np.linspace(0.0, 0.1, 64)[None, :, None] * np.ones((64, 1, 3))
    >>> featureless(noise + glare)
    False
    """
    img = np.asarray(image, float)
    m = np.ones(img.shape[:2], bool) if mask is None else mask
    for k in range(img.shape[-1]):
        low, high = np.percentile(img[..., k][m], [1, 99])
        if high - low > FLAT_NOISE * image_noise_sd(img[..., k], m):
            return False
    return True


def brightest_channel(image: np.ndarray, mask: np.ndarray | None = None) -> int:
    """The channel of a colour photograph with the highest mean: the colour of the light
    where it shows no pattern (:func:`featureless`), whose channels have no range to tell.

    Parameters
    ----------
    image : (rows, cols, 3) float array
    mask : (rows, cols) bool array, optional
        Pixels that decide (default all).

    Returns
    -------
    int
        0, 1 or 2 (red, green, blue).

    Examples
    --------
    >>> import numpy as np
    >>> brightest_channel(np.ones((4, 4, 3)) * np.array([0.003, 0.02, 0.006]))
    1
    """
    img = np.asarray(image, float)
    m = np.ones(img.shape[:2], bool) if mask is None else mask
    return int(np.argmax(img[m].mean(axis=0)))
