"""``fringekit invert``: :func:`~fringekit.inversion.loads.invert`, then its folder.

The folder's files are those of :meth:`~fringekit.inversion.loads.Inversion.write`; it is
written beside ``--out`` and swapped in when the run ends, so a failed run leaves an
earlier result intact.
"""

from __future__ import annotations

from fringekit.inversion.budget import DEFAULT_MAX_SECONDS
from fringekit.inversion.loads import invert
from fringekit.output.folders import as_paths, claim_output

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
    inputs = [
        *as_paths(images),
        *as_paths(reference),
        *as_paths(residual_steps),
        getattr(library, "folder", library),
        sensor,
    ]
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
