"""Shared plumbing of the examples: configs, one predict run per case, argument parsing.

Every example runs at two settings: the default (the reference sensor, 20 mm field of
view, the meshes of ``fringekit predict``) and ``--coarse`` (the 12 x 12 mm block on 4 mm
of polycarbonate and small images that the test suite uses, so that a test runs each
example in seconds to a minute). Solutions are cached (``$FRINGEKIT_CACHE_DIR``), so
examples that share a case solve it once.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fringekit.config.files import apply_overrides, load_config
from fringekit.prediction.pipeline import run_predict

#: Overrides that turn the reference case into the coarse test block.
COARSE = {
    "sheet.width_mm": 12.0,
    "sheet.length_mm": 12.0,
    "substrate.thickness_mm": 4.0,
    "mesh.h_contact_mm": 1.0,  # 0.6 makes the stuck shear case take ~100 s instead of 12 s
    "mesh.refine_radius_mm": 1.5,
    "mesh.h_sheet_mm": 1.5,
    "mesh.h_far_mm": 3.0,
    "mesh.growth": 0.5,
    "optics.field_of_view_mm": 10.0,
    "optics.pixels": 96,
    "optics.samples_per_ray": 24,
    "optics.white_light_wavelengths": 16,
}


def parse_args(description: str, argv=None, extra=None) -> argparse.Namespace:
    """The examples' common options; ``extra(parser)`` adds an example's own."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--coarse", action="store_true", help="the small test block (fast)")
    p.add_argument("--out", default=None, help="output folder (default examples-out/<name>)")
    p.add_argument("--cache-dir", default=None, help="mesh and solution cache root")
    p.add_argument("--quiet", action="store_true")
    if extra is not None:
        extra(p)
    return p.parse_args(argv)


def out_dir(args, name: str) -> Path:
    out = Path(args.out) if args.out else Path("examples-out") / name
    out.mkdir(parents=True, exist_ok=True)
    return out


#: The coarse setting of the examples that compare fringe orders pixel by pixel up to the
#: contact edge (figs. 6-9 and the coarse foot): 0.5 mm elements in the contact zone.
#: With the 1 mm of :data:`COARSE`, about one element spans the 1.15 mm contact radius;
#: the stress under the contact edge is then far from axisymmetric, its secondary
#: principal axes turn through the thickness, and within 1 mm of the contact the
#: characteristic order differs from the simple order by up to 0.09-0.24 fringe
#: (0.07-0.14 at 0.5 mm). Near whole and half orders it is two-valued (N = k +- delta,
#: which no phase-shifting measurement tells apart), so six-step and prediction disagreed
#: by such mirror images: worst reliable pixel 0.06-1.07 fringe on 8 fresh 1 mm meshes,
#: whole bands on two of them; 0.05-0.36 on 30 fresh meshes at 0.5 mm, at most 24 pixels
#: (0.3 %) off by more than 0.1 (fig9 14-24 s cold).
COARSE_EDGE = {"mesh.h_contact_mm": 0.5}


def coarse_overrides(edge: bool = False) -> dict:
    """:data:`COARSE`, with the contact zone of :data:`COARSE_EDGE` when ``edge``."""
    return {**COARSE, **(COARSE_EDGE if edge else {})}


def config(overrides: dict, coarse: bool, base: str = "reference", edge: bool = False) -> dict:
    """The effective config: a built-in case, the coarse block if asked, then overrides.

    ``edge`` refines the coarse block's contact zone (:data:`COARSE_EDGE`); it has no
    effect at the default setting.
    """
    coarse_keys = coarse_overrides(edge) if coarse else {}
    return apply_overrides(load_config(base), {**coarse_keys, **overrides})


def predict(cfg: dict, out: Path, args) -> tuple[dict, Path]:
    """``fringekit predict`` into ``out``; returns (summary, folder of the last state)."""
    summary = run_predict(cfg, out, cache_dir=args.cache_dir, progress=not args.quiet)
    return summary, out / summary["rendered"][-1]["folder"]


def maps(state: Path) -> dict:
    with np.load(state / "maps.npz") as z:
        return {k: np.array(z[k]) for k in z.files}


def six_images(state: Path) -> list[Path]:
    return [state / "six_step" / f"step{k}.png" for k in range(1, 7)]


def write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=2, default=float))


def centre_rc(m: dict) -> tuple[float, float]:
    r, c = m["indenter_rc"][0]
    return float(r), float(c)


def extent_mm(m: dict) -> tuple[float, float, float, float]:
    """imshow extent (left, right, bottom, top) in mm of a predict ``maps.npz``."""
    return (
        m["x_m"][0, 0] * 1e3,
        m["x_m"][0, -1] * 1e3,
        m["y_m"][-1, 0] * 1e3,
        m["y_m"][0, 0] * 1e3,
    )


def contact_mask(summary: dict, m: dict, margin_px: float = 2.0) -> np.ndarray:
    """Pixels over the sheet outside the first indenter's contact circle + a margin (the
    centre an experimenter masks)."""
    from fringekit.analysis import exclude_circle

    a_px = summary["indenters"][0]["contact_radius_mm"] * 1e-3 / float(m["pixel_size_m"])
    return exclude_circle(np.isfinite(m["fringe_order"]), centre_rc(m), a_px + margin_px)


def six_step_of(state: Path, mask: np.ndarray):
    """The six-step result (analysis.six_step) of a predicted state's step images."""
    from fringekit.analysis import load_six_step, six_step

    return six_step(load_six_step(six_images(state)), mask=mask)
