"""The memory a request will need, estimated before its big arrays are made, against the
memory this machine has free.

A value inside an option's allowed range can still ask for more memory than any machine
has (``--smooth-px 1e9``, ``optics.pixels = 4096`` with 4096 samples per ray); numpy then
raises ``MemoryError`` when the array is made, often after minutes of solving. Each
command estimates its largest arrays from the problem's sizes (shape x bytes per item x
arrays alive at once, written beside each estimate) and :func:`check_memory` refuses the
request in one line, naming the option, its value and the estimate, before any work.

The estimates are of the largest arrays, not of the whole process (Python, the libraries
and the smaller arrays come on top): a request that passes can still run short, one that
is refused would not have finished.

Examples
--------
>>> from fringekit._memory import gaussian_bytes, size_text
>>> size_text(gaussian_bytes(1e9))
'179 GiB'
"""

from __future__ import annotations

import os

from fringekit.errors import InputError

__all__ = ["check_memory", "free_bytes", "gaussian_bytes", "size_text"]

#: Bytes per element of float64 and int64 arrays.
F8 = 8


def free_bytes() -> int | None:
    """The memory this machine can give a new process now (bytes): ``MemAvailable`` of
    ``/proc/meminfo`` (free memory and the caches the kernel can drop), else the free
    physical pages (``os.sysconf``); None where neither is known.

    Examples
    --------
    >>> from fringekit._memory import free_bytes
    >>> n = free_bytes()
    >>> n is None or n > 0
    True
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def size_text(n: float) -> str:
    """``n`` bytes in binary units, three significant digits.

    Examples
    --------
    >>> from fringekit._memory import size_text
    >>> size_text(1.92e13), size_text(21_800_000_000), size_text(512)
    ('17.5 TiB', '20.3 GiB', '512 B')
    """
    units = ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB")
    k = 0
    while n >= 1024 and k < len(units) - 1:
        n /= 1024.0
        k += 1
    return f"{n:.0f} B" if k == 0 else f"{n:.3g} {units[k]}"


def gaussian_bytes(sigma_px: float, n_pixels: int = 0) -> float:
    """Memory (bytes) of a Gaussian filter of ``sigma_px`` (scipy.ndimage) on an image of
    ``n_pixels``: its kernel of 2 * round(4 sigma) + 1 taps, made as int64 positions,
    their float64 squares and float64 weights (3 arrays alive at once), and the filtered
    float64 image with its output (2 arrays).

    Examples
    --------
    >>> from fringekit._memory import gaussian_bytes
    >>> gaussian_bytes(0.5, 100)  # 5 taps
    1720.0
    """
    taps = 2 * int(4.0 * float(sigma_px) + 0.5) + 1
    return float(3 * taps * F8 + 2 * n_pixels * F8)


def check_memory(
    need: float, what: str, option: str, *, hint: str = "", error=InputError, free=None
) -> None:
    """Refuse a request whose largest arrays need more than the memory free.

    Parameters
    ----------
    need : float
        The estimate (bytes).
    what : str
        What the memory is for, with its sizes ("detection's smoothing kernel of 4.8e+12
        taps").
    option : str
        The option or config key and its value, as the user gave them
        ("--smooth-px 1e+09", "optics.pixels = 4096").
    hint : str
        What to do instead, appended after a semicolon.
    error : type
        The error raised (:class:`~fringekit.errors.InputError` for an option,
        :class:`~fringekit.errors.ConfigError` for a config key).
    free : int, optional
        The memory free (bytes); default :func:`free_bytes` (unknown: nothing refused).

    Raises
    ------
    InputError
        (or ``error``) in one line when ``need`` exceeds ``free``.

    Examples
    --------
    >>> from fringekit._memory import check_memory
    >>> check_memory(2**40, "the kernel", "--smooth-px 1e+09", free=2**30)
    Traceback (most recent call last):
    ...
    fringekit.errors.InputError: --smooth-px 1e+09 needs about 1 TiB for the kernel; this ...
    """
    free = free_bytes() if free is None else free
    if free is None or need <= free:
        return
    raise error(
        f"{option} needs about {size_text(need)} for {what}; this machine has "
        f"{size_text(free)} free" + (f"; {hint}" if hint else "")
    )
