"""The stated uncertainty of an inversion: 1-sigma that covers the error.

The joint fit's residual is not white noise: where the library's image differs from the
sensor's (a coarser mesh, interpolation between its loads, the camera's 8 bits) it
differs over whole fringes, so neighbouring pixels err together. Treating the pixels as
independent stated 1-sigma 3-6 times smaller than the median error on the coarse bench's
FEM images, and up to 24 times smaller than the largest. Two terms correct it:

1. :func:`correlation_area`: the correlation area ``A`` (pixels) of each parameter's
   score image (its Jacobian column times the residual), so that the fit has about
   ``N / A`` independent pixels for it rather than ``N``; its independent-pixel
   variance is scaled by ``A`` (:func:`stated_sd`).
2. a model-error floor per parameter (:data:`MODEL_SD`), calibrated on the FEM images
   of ``bench/invert.py``: the part of the library's error that the fit absorbs into the
   parameters and so leaves no trace in the residual.

The first term is the whole answer where the model is exact (library images with
camera noise); the second dominates on the FEM images of the coarse bench.
"""

from __future__ import annotations

import numpy as np

from fringekit.inversion.model import N_PARAMS

__all__ = [
    "MODEL_SD",
    "MODEL_SD_RATIO_STEP",
    "RHO_STOP",
    "COVERAGE_GROUPS",
    "correlation_area",
    "coverage",
    "floor_sd",
    "model_sd",
    "parameter_sd",
    "stated_sd",
]

#: The model-error floor: 1-sigma of x and y (mm), and of Fz, Fx and Fy as fractions of
#: the indenter's Fz, added in quadrature to the correlated-noise sd. Set on the coarse
#: bench (``bench/invert.py --preset coarse --n-indenters 1 2 --seed 0 1 2``, methods
#: rgb, mono and phase: 27 fits, 9 indenters of 6 FEM solves, 2026-11-25) as the smallest
#: floor per quantity that puts 68 % of its errors within 1 sd: 0.043 mm, 2.2 % and
#: 1.07 % of Fz (the bench then gave 67-69 % within 1 sd and 93-100 % within 2 on those
#: seeds, and on seeds 3-5, held out, 53-93 % and 90-100 %). The library on the
#: coarse 0.6 mm contact mesh reads Fz about 2 % low on almost every image: an error
#: the fit takes into the parameters, so that no residual shows it. Measured with the
#: coarse library only: a library on a finer mesh should err less (not measured).
MODEL_SD = np.array([0.043, 0.043, 0.022, 0.011, 0.011])
#: The largest tangential-ratio step of the library MODEL_SD was set with (the default
#: grid's, 0.2): the tangential floor scales with the square of a library's step
#: (:func:`model_sd`).
MODEL_SD_RATIO_STEP = 0.2

#: The autocorrelation is integrated out to the first radius where its radial mean falls
#: to this fraction of its value at lag 0: the sample autocorrelation of N / A
#: independent values is noisy by about sqrt(A / N) at each lag, and a Gaussian
#: autocorrelation loses this fraction of its area.
RHO_STOP = 0.05


def correlation_area(field, mask=None) -> float:
    """Correlation area (pixels) of a residual image: how many pixels count as one.

    The integral of the residual's normalised autocorrelation over the lags (the 2-D
    form of the integral time scale), so that ``N`` pixels carry ``N / A`` independent
    values: the effective number of observations of Bayley and Hammersley (1946, "The
    'effective' number of independent observations in an autocorrelated time series",
    J. R. Stat. Soc. Suppl. 8, 184-197), ``N_eff = N / sum_h rho(h)``. The
    autocorrelation is that of the masked image, each lag divided by its number of
    pixel pairs (Padfield 2012, "Masked object registration in the Fourier domain",
    IEEE Trans. Image Process. 21, 2706-2718), by zero-padded FFTs. The channels are
    summed first, so that channels that err together count as one (three colour
    channels of one misfit fringe are not three observations). The sum of a sample
    autocorrelation over every lag is zero (the mean is removed), so the integral is
    taken over the lags out to the first radius (in whole pixels) at which the radial
    mean of the autocorrelation falls to :data:`RHO_STOP` of its value at lag 0: on
    fields of known autocorrelation (white noise filtered by Gaussians of 1.5-3 pixels,
    256 x 256) this gave 0.89-1.07 of the exact area, 0.96 on average.

    Parameters
    ----------
    field : (rows, cols) or (rows, cols, C) array_like
        The residual image (any unit; C channels).
    mask : (rows, cols) bool array_like, optional
        The pixels that hold residuals; default every pixel.

    Returns
    -------
    float
        The correlation area in pixels of the image's grid, between 1 (independent
        pixels) and the number of pixels in the mask.

    Examples
    --------
    White noise has a correlation area of one pixel; the same noise averaged over 3 x 3
    pixels has one of about 9 (the exact value for a box filter of width w is w**2):

    >>> import numpy as np
    >>> from scipy import ndimage
    >>> noise = np.random.default_rng(0).normal(size=(200, 200))
    >>> round(correlation_area(noise), 1)
    1.0
    >>> round(correlation_area(ndimage.uniform_filter(noise, 3, mode="wrap")))
    9
    """
    f = np.asarray(field, float)
    f = f[..., None] if f.ndim == 2 else f
    m = np.ones(f.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    n = int(m.sum())
    if n < 2:
        return 1.0
    f = np.where(m[..., None], f - f[m].mean(axis=0), 0.0)
    var = float(np.sum(f**2)) / n  # the channels' variances, summed
    if var == 0.0:
        return 1.0
    rows, cols = m.shape
    shape = (2 * rows, 2 * cols)  # zero padding: linear, not circular, correlation
    s = np.fft.rfft2(f.sum(axis=-1), shape)
    w = np.fft.rfft2(m.astype(float), shape)
    acov = np.fft.irfft2(s * np.conj(s), shape)
    pairs = np.rint(np.fft.irfft2(w * np.conj(w), shape))
    ok = pairs >= 0.25 * n  # lags with few pairs are noise
    rho = np.where(ok, acov / np.maximum(pairs, 1.0) / var, 0.0)
    dy = np.fft.fftfreq(shape[0], 1.0 / shape[0])
    dx = np.fft.fftfreq(shape[1], 1.0 / shape[1])
    ring = np.rint(np.hypot(dy[:, None], dx[None, :])).astype(int)
    counts = np.bincount(ring[ok], minlength=ring.max() + 1)
    profile = np.bincount(ring[ok], rho[ok], minlength=ring.max() + 1)
    profile = profile / np.maximum(counts, 1)
    stop = np.flatnonzero((profile <= RHO_STOP * profile[0]) | (counts == 0))
    first = int(stop[stop > 0][0]) if np.any(stop > 0) else len(profile)
    area = float(np.sum(rho[ok & (ring <= first)]))
    return float(np.clip(area, 1.0, n))


def parameter_sd(jac, residual, n_used: int) -> np.ndarray:
    """1-sigma of the parameters as if the residuals were independent.

    The Gauss-Newton covariance ``s2 (J^T J)^-1`` with ``s2`` the residual variance on
    ``n_used - K`` degrees of freedom. Model selection asks it whether an indenter's
    fringes stand out of the noise at all (its Fz above 3 sd); the stated uncertainty is
    :func:`stated_sd`, which starts from it.

    Parameters
    ----------
    jac : (M, K) array
        The Jacobian of the residuals at the solution.
    residual : (M,) array
        The residuals at the solution (zero where nothing was fitted).
    n_used : int
        The number of residuals fitted.

    Returns
    -------
    (K,) array
        1-sigma of each parameter, in the parameters' units (NaN when the Jacobian has
        no pseudo-inverse).

    Examples
    --------
    A straight line through four points: the slope's sd is that of ordinary least
    squares, ``sqrt(s2 / sum((x - mean x)**2))`` on two degrees of freedom:

    >>> import numpy as np
    >>> x = np.array([0.0, 1.0, 2.0, 3.0])
    >>> J = np.stack([x, np.ones(4)], axis=1)
    >>> r = np.array([0.1, -0.1, -0.1, 0.1])
    >>> np.round(parameter_sd(J, r, 4), 4)
    array([0.0632, 0.1183])
    """
    J = np.asarray(jac, float)
    dof = max(n_used - J.shape[1], 1)
    s2 = float(np.sum(np.asarray(residual, float) ** 2)) / dof
    try:
        cov = np.linalg.pinv(J.T @ J) * s2
    except np.linalg.LinAlgError:
        return np.full(J.shape[1], np.nan)
    return np.sqrt(np.clip(np.diag(cov), 0.0, None))


def stated_sd(
    jac, residual, shape, params, model_sd=MODEL_SD, area=None
) -> tuple[np.ndarray, np.ndarray]:
    """The stated 1-sigma of every indenter's parameters, and the correlation areas they
    rest on.

    A least-squares estimate moves with the sum of its score terms ``g_i = J_ik r_i``
    over the pixels and channels: correlated terms make that sum vary ``A`` times more
    than independent ones would (Bayley and Hammersley's effective number of
    observations, :func:`correlation_area`, here of the score image rather than of the
    residual; for a parameter that moves every pixel alike the two are the same). So
    each parameter's independent-pixel sd (:func:`parameter_sd`) is scaled by the
    square root of its score image's correlation area, and the model-error floor
    ``model_sd`` is added in quadrature. The score rather than the residual: the six
    phase steps' residuals cancel in their sum (their steps are in opposite phases), and
    so do their Jacobians, but not the products.

    Parameters
    ----------
    jac : (M, 5 n) array
        The Jacobian of the residuals at the solution.
    residual : (M,) array
        The residuals at the solution: first the image's ``rows * cols * C`` (pixel by
        pixel, the channels innermost; zero where not fitted), then any penalty terms.
    shape : (rows, cols, C)
        The fitted image's grid and channels.
    params : (n, 5) array
        x, y (mm), Fz, Fx, Fy (N) of each indenter.
    model_sd : (5,) array
        The floor: 1-sigma of x and y (mm), and of Fz, Fx and Fy as fractions of Fz.
    area : (n, 5) array, optional
        Correlation areas to use instead of measuring them (a tracker measures them
        every few frames: they change slowly while the image does).

    Returns
    -------
    sd : (n, 5) array
        1-sigma of x, y (mm), Fz, Fx, Fy (N).
    area : (n, 5) array
        The correlation area of each parameter's score image (pixels of the fitted
        grid; 1 where the residuals are independent).

    Examples
    --------
    One indenter whose parameters move every pixel alike, fitted to residuals that err
    in blocks of 2 x 2 pixels: correlation areas of about 4 pixels, and every sd twice
    the independent-pixel one:

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> r = np.kron(rng.normal(size=(64, 64)), np.ones((2, 2))).ravel()
    >>> J = np.ones((128 * 128, 5)) * np.arange(1.0, 6.0)  # five multiples of an offset
    >>> p = np.array([[0.0, 0.0, 2.0, 0.5, 0.0]])
    >>> sd, area = stated_sd(J, r, (128, 128, 1), p, model_sd=np.zeros(5))
    >>> np.round(area, 1), np.round(sd / parameter_sd(J, r, 128 * 128), 2)
    (array([[4.1, 4.1, 4.1, 4.1, 4.1]]), array([[2.03, 2.03, 2.03, 2.03, 2.03]]))

    With the floor, a 2 N indenter's Fz sd is at least ``model_sd[2] * 2`` N:

    >>> sd, _ = stated_sd(J, r, (128, 128, 1), p, model_sd=np.array([0.05, 0.05, 0.1, 0, 0]))
    >>> bool(sd[0, 2] >= 0.2), bool(sd[0, 0] >= 0.05)
    (True, True)
    """
    rows, cols, C = shape
    r = np.asarray(residual, float)
    image = r[: rows * cols * C].reshape(rows, cols, C)
    mask = np.any(image != 0.0, axis=-1)
    J = np.asarray(jac, float)[: rows * cols * C].reshape(rows, cols, C, -1)
    q = np.asarray(params, float).reshape(-1, N_PARAMS)
    if area is None:
        area = np.array(
            [correlation_area(J[..., k] * image, mask) for k in range(J.shape[-1])]
        ).reshape(q.shape)
    sd = parameter_sd(jac, r, int(np.count_nonzero(r))).reshape(q.shape) * np.sqrt(area)
    return np.sqrt(sd**2 + floor_sd(model_sd, q) ** 2), area


def floor_sd(model_sd, params, least_load_N: float = -np.inf) -> np.ndarray:
    """The model-error floor in the parameters' own units: x and y (mm) as given, the
    loads' fractions times each indenter's Fz (or ``least_load_N``, if larger).

    Parameters
    ----------
    model_sd : (5,) array_like
        1-sigma of x and y (mm), and of Fz, Fx and Fy as fractions of Fz
        (:func:`model_sd`).
    params : (n, 5) array_like
        x, y (mm), Fz, Fx, Fy (N) of each indenter.
    least_load_N : float
        The least Fz the load fractions are taken of (N; default: each Fz as it is).

    Returns
    -------
    (n, 5) array
        1-sigma of x, y (mm), Fz, Fx, Fy (N).

    Examples
    --------
    >>> floor_sd([0.04, 0.04, 0.02, 0.01, 0.01], [[0.0, 0.0, 3.0, 0.2, 0.0]])
    array([[0.04, 0.04, 0.06, 0.03, 0.03]])
    >>> floor_sd([0.04, 0.04, 0.02, 0.01, 0.01], [[0.0, 0.0, 0.5, 0.0, 0.0]], 2.0)
    array([[0.04, 0.04, 0.04, 0.02, 0.02]])
    """
    q = np.asarray(params, float).reshape(-1, N_PARAMS)
    scale = np.ones_like(q)
    scale[:, 2:] = np.maximum(q[:, 2:3], least_load_N)
    return np.asarray(model_sd, float) * scale


def model_sd(shear_ratio) -> np.ndarray:
    """The model-error floor (:data:`MODEL_SD`) for a library of these tangential ratios.

    The library's fields are interpolated linearly between its ratios, which errs as
    the square of the step; so the tangential terms are MODEL_SD's times
    ``(step / MODEL_SD_RATIO_STEP)**2`` (never less than MODEL_SD's). On the tests'
    library (ratios 0, 0.4, 0.8) two FEM images' tangential errors were 4.0-4.8 % of Fz
    where the default grid's (steps of 0.2) were at most 3.3 %, their median 0.7 %.

    Parameters
    ----------
    shear_ratio : (nS,) array_like
        The library's tangential / normal load ratios (increasing, from 0).

    Returns
    -------
    (5,) array
        1-sigma floor of x, y (mm) and of Fz, Fx, Fy as fractions of Fz.

    Examples
    --------
    >>> import numpy as np
    >>> model_sd([0.0, 0.2, 0.4, 0.6, 0.8])[3:] / MODEL_SD[3:]
    array([1., 1.])
    >>> model_sd([0.0, 0.4, 0.8])[3:] / MODEL_SD[3:]
    array([4., 4.])
    """
    r = np.asarray(shear_ratio, float)
    step = float(np.max(np.diff(r))) if len(r) > 1 else MODEL_SD_RATIO_STEP
    out = MODEL_SD.copy()
    out[3:] *= max(step / MODEL_SD_RATIO_STEP, 1.0) ** 2
    return out


#: The quantities a coverage is given for, and their columns in x, y, Fz, Fx, Fy order.
COVERAGE_GROUPS = {"position": (0, 1), "Fz": (2,), "tangential": (3, 4)}


def coverage(z) -> dict:
    """How well a stated 1-sigma covers the errors it claims to: per quantity, the
    fractions of the errors within 1 and 2 of their sd (0.683 and 0.954 for a normal
    error and a right sd; more where the sd are cautious, fewer where they claim more
    than the method holds).

    Parameters
    ----------
    z : (n, 5) array_like
        Each error (estimate minus truth) over its stated sd, in the order x, y, Fz, Fx,
        Fy; NaN where a component was not scored (or its sd was zero).

    Returns
    -------
    dict
        :data:`COVERAGE_GROUPS`' names ("position", "Fz", "tangential") -> ``n`` (the
        number of normalised errors), ``within_1sd``, ``within_2sd`` and ``median_z``
        (the median of their magnitudes), each None when ``n`` is 0.

    Examples
    --------
    >>> import numpy as np
    >>> z = np.array([[0.5, -1.5, 0.2, 3.0, np.nan], [0.1, 0.9, -2.5, 0.3, 0.4]])
    >>> c = coverage(z)
    >>> c["position"]["n"], c["position"]["within_1sd"], c["position"]["within_2sd"]
    (4, 0.75, 1.0)
    >>> c["tangential"]["n"], round(c["tangential"]["within_1sd"], 3)
    (3, 0.667)
    """
    a = np.abs(np.asarray(z, float).reshape(-1, N_PARAMS))
    out = {}
    for name, cols in COVERAGE_GROUPS.items():
        v = a[:, cols].ravel()
        v = v[np.isfinite(v)]
        some = len(v) > 0
        out[name] = {
            "n": len(v),
            "within_1sd": float(np.mean(v <= 1.0)) if some else None,
            "within_2sd": float(np.mean(v <= 2.0)) if some else None,
            "median_z": float(np.median(v)) if some else None,
        }
    return out
