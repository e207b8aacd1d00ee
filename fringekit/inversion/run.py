"""``fringekit invert``: :func:`~fringekit.inversion.loads.invert`, then its folder.

The folder's files are those of :meth:`~fringekit.inversion.loads.Inversion.write`; it is
written beside ``--out`` and swapped in when the run ends, so a failed run leaves an
earlier result intact.
"""

from __future__ import annotations

import os

from fringekit.inversion.budget import DEFAULT_MAX_SECONDS
from fringekit.inversion.loads import invert
from fringekit.output.folders import claim_output

__all__ = ["run_invert"]


def run_invert(
    images,
    library,
    out,
    *,
    method=None,
    pixel_mm=None,
    origin_px=None,
    sensor=None,
    reference=None,
    residual_steps=None,
    refine=None,
    max_seconds=DEFAULT_MAX_SECONDS,
    progress=True,
    echo=print,
) -> dict:
    """Invert one image (or six) against a library; write ``out``; return the summary
    (``stopped_after`` set when the time budget cut the fit short: the folder holds that
    answer, flagged)."""
    paths = [images] if isinstance(images, (str, os.PathLike)) else list(images)
    rest = [reference] if isinstance(reference, (str, os.PathLike)) else list(reference or [])
    steps = list(residual_steps or [])
    inputs = [*paths, *rest, *steps, getattr(library, "folder", library), sensor]
    with claim_output(out, command="invert", inputs=inputs) as work:
        inv = invert(
            images,
            library,
            pixel_mm=pixel_mm,
            origin_px=origin_px,
            method=method,
            sensor=sensor,
            reference=reference,
            residual_steps=residual_steps,
            refine=refine,
            max_seconds=max_seconds,
            progress=progress,
            echo=echo,
        )
        inv.write(work)
    return inv.summary
