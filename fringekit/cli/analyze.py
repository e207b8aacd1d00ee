"""``fringekit analyze``: image files -> fringe order, the method's maps, figures and a profile
(:func:`fringekit.analyze`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fringekit.cli.options import (
    DISC_DIAMETER_MM,
    MAX_ORDER,
    PIXEL_MM,
    SMOOTH_PX,
    WINDOW,
    finite,
    fraction,
    in_range,
    origin_px_option,
    pixel,
)
from fringekit.errors import InputError
from fringekit.measurement import (
    MonoOptions,
    PhaseOptions,
    Region,
    RGBOptions,
    analyze,
    choose_method,
)
from fringekit.output.folders import claim_output

__all__ = ["add_parser", "run"]


def _mono_options(g) -> None:
    g.add_argument(
        "--field",
        choices=("dark", "bright"),
        default="dark",
        help="(mono) polariscope field: whole orders are dark fringes in dark "
        "field, bright ones in bright field",
    )
    g.add_argument(
        "--flat",
        default=None,
        help="(mono) flat-field image: the light without the specimen's "
        "retardation (bright field, unloaded); default: the fringe envelope",
    )
    g.add_argument(
        "--smooth-px",
        type=in_range(SMOOTH_PX),
        default=0.5,
        help="(mono) Gaussian smoothing before normalising (px)",
    )


def _region_options(an) -> None:
    """The output, the region of interest, the frame and the anchors."""
    an.add_argument("--out", default=None, help="output folder (default fringekit-out/analysis)")
    an.add_argument("--dark", default=None, help="dark frame subtracted from every image")
    an.add_argument("--roi-circle", nargs=3, type=finite, metavar=("ROW", "COL", "R"))
    an.add_argument(
        "--roi-rect",
        nargs=4,
        type=finite,
        metavar=("R0", "C0", "R1", "C1"),
        help="rectangular region of interest (corners, px)",
    )
    an.add_argument(
        "--roi-polygon",
        nargs="+",
        type=pixel,
        metavar="ROW,COL",
        help="polygonal region of interest (3 or more vertices, px)",
    )
    an.add_argument(
        "--exclude-polygon",
        nargs="+",
        type=pixel,
        action="append",
        metavar="ROW,COL",
        help="masked polygon (crack, label, load point); two vertices mask a line 3 px wide",
    )
    an.add_argument(
        "--exclude-circle",
        nargs=3,
        type=finite,
        action="append",
        metavar=("ROW", "COL", "R"),
        help="masked circle, e.g. the indenter",
    )
    an.add_argument(
        "--mask",
        default=None,
        metavar="PNG",
        help="mask image of the images' size, data where bright (predict's mask.png); "
        "predict's no-data fill is left out without it too",
    )
    an.add_argument(
        "--pixel-mm", type=in_range(PIXEL_MM), default=None, help="pixel pitch on the sheet (mm)"
    )
    an.add_argument(
        "--roi-disc",
        type=in_range(DISC_DIAMETER_MM),
        default=None,
        metavar="DIAMETER_MM",
        help="find the circular specimen of this diameter in the (first) image: "
        "the region of interest, the pixel size and the origin",
    )
    an.add_argument(
        "--anchor-order",
        type=finite,
        default=0.0,
        help="fringe order of the image border ring (phase, mono; rgb without --seed)",
    )


def _phase_options(g) -> None:
    """Options of the six-step phase method."""
    g.add_argument("--min-modulation", type=fraction, default=0.1)
    g.add_argument(
        "--reference",
        nargs="+",
        default=None,
        metavar="IMAGE",
        help="(phase) the six images (or a 6-page TIFF) of the unloaded specimen: "
        "their residual retardation is subtracted vectorially",
    )
    g.add_argument(
        "--fold",
        choices=("count", "isoclinic"),
        default="count",
        help="(phase) resolve the folded phase by counting fringes from the "
        "anchor, or by the isoclinic's continuity; the other checks it",
    )


def _rgb_options(g) -> None:
    """Options of the white-light colour method."""
    g.add_argument(
        "--colour-table", default=None, help="(rgb) colour calibration table CSV: order,R,G,B"
    )
    g.add_argument("--light", default="LED", help="(rgb) light of the synthetic chart")
    g.add_argument("--camera", default="CIE1931", help="(rgb) camera of the synthetic chart")
    g.add_argument(
        "--max-order",
        type=in_range(MAX_ORDER),
        default=7.0,
        help="(rgb) chart range (fringe orders; colours wash out past about 6.5)",
    )
    g.add_argument(
        "--exposure",
        type=in_range("optics.exposure"),
        default=0.9,
        help="(rgb) chart exposure, as in predict's optics.exposure",
    )
    g.add_argument(
        "--seed",
        nargs=3,
        type=finite,
        action="append",
        metavar=("ROW", "COL", "N"),
        help="(rgb) pixel of known order: the refined search starts from it (and from "
        "--order-at); without either, from the image border at --anchor-order",
    )
    g.add_argument(
        "--window", type=in_range(WINDOW), default=0.25, help="(rgb) refined window (fringe)"
    )
    g.add_argument(
        "--search",
        choices=("refined", "plain"),
        default="refined",
        help="(rgb) refined: follow the fringe order from the seeds (to about order 6.5); "
        "plain: every pixel against the whole table (to about order 3)",
    )
    g.add_argument(
        "--adapt",
        choices=("auto", "seeds", "off"),
        default="auto",
        help="(rgb, refined) fit the table's colours to the image: to the seeds and the "
        "pixels solved below order 3 (auto), to the seeds only (a no-load region), or not",
    )


def add_parser(sub) -> None:
    an = sub.add_parser(
        "analyze", help="fringe order from six phase-stepped, one RGB or one monochrome image"
    )
    an.add_argument(
        "images",
        nargs="+",
        help="six step images (or a 6-page TIFF), one RGB or one monochrome image",
    )
    an.add_argument(
        "--method",
        choices=("phase", "rgb", "mono"),
        default=None,
        help="default: rgb for one colour PNG/JPEG, mono for one grey image, phase otherwise",
    )
    _mono_options(an.add_argument_group("mono: one monochrome photograph"))
    an.add_argument(
        "--points",
        default=None,
        metavar="FILE.csv",
        help="CSV with header row,col or x_mm,y_mm: writes points.csv with "
        "row,col,x_mm,y_mm,order,order_sd,reliable",
    )
    _region_options(an)
    _phase_options(an.add_argument_group("phase: six phase-stepped images"))
    _rgb_options(an.add_argument_group("rgb: one white-light colour image"))
    an.add_argument("--line", nargs=4, type=finite, metavar=("R0", "C0", "R1", "C1"))
    an.add_argument(
        "--order-at",
        nargs=3,
        type=finite,
        action="append",
        metavar=("ROW", "COL", "N"),
        default=None,
        help="a pixel of known fringe order N, the lowest order about it (it "
        "also fixes the sign), instead of the image border at --anchor-order; repeat it "
        "for every low point the count cannot reach by counting up (a disc's two ends)",
    )
    origin_px_option(
        an,
        "pixel of the sensor origin: figures and profile.csv use x right, "
        "y up in mm about it (default: the image centre)",
    )
    an.add_argument(
        "--strict",
        action="store_true",
        help="exit 1 when less than half of the region of interest is reliable",
    )
    an.add_argument(
        "--f-sigma-N-per-m",
        type=in_range("optics.f_sigma_N_per_m"),
        default=None,
        help="material fringe value: with --thickness-mm, a stress map",
    )
    an.add_argument(
        "--thickness-mm",
        type=in_range("sheet.thickness_mm"),
        default=None,
        help="sheet thickness (mm): with --f-sigma-N-per-m, a stress map",
    )
    an.add_argument("--quiet", action="store_true")
    an.set_defaults(func=run)


def roi_polygon(args: argparse.Namespace):
    """The polygonal region of interest of ``--roi-rect`` or ``--roi-polygon`` (px)."""
    if args.roi_rect is not None and args.roi_polygon is not None:
        raise InputError("give --roi-rect or --roi-polygon, not both")
    if args.roi_rect is not None:
        r0, c0, r1, c1 = args.roi_rect
        return [(r0, c0), (r0, c1), (r1, c1), (r1, c0)]
    if args.roi_polygon is not None and len(args.roi_polygon) < 3:
        raise InputError(
            f"--roi-polygon has {len(args.roi_polygon)} vertices; allowed: 3 or more ROW,COL"
        )
    return args.roi_polygon


def run(args: argparse.Namespace) -> int:
    out = Path(args.out or "fringekit-out/analysis")
    region = Region(
        circle=tuple(args.roi_circle) if args.roi_circle else None,
        polygon=roi_polygon(args),
        exclude_circles=[tuple(e) for e in args.exclude_circle or []],
        exclude_polygons=[tuple(map(tuple, p)) for p in args.exclude_polygon or []],
        disc_diameter_mm=args.roi_disc,
        mask=args.mask,
    )
    options = {
        "phase": lambda: PhaseOptions(args.min_modulation, args.fold, args.reference),
        "rgb": lambda: RGBOptions(
            args.colour_table,
            args.light,
            args.camera,
            args.max_order,
            args.exposure,
            tuple(tuple(s) for s in args.seed or []),
            args.window,
            args.search,
            args.adapt,
        ),
        "mono": lambda: MonoOptions(args.field, args.flat, args.smooth_px),
    }
    method = choose_method(args.method, [str(p) for p in args.images])
    if args.reference and method != "phase":
        raise InputError(
            f"--reference is for --method phase (six zero-load images); the {method} method "
            "has none (calibrate --disc takes a zero-load photo)"
        )
    given = [
        *args.images,
        *(args.reference or []),
        args.dark,
        args.flat,
        args.colour_table,
        args.mask,
    ]
    with claim_output(out, command="analyze", inputs=[*given, args.points]) as work:
        an = analyze(
            args.images,
            method=method,
            pixel_mm=args.pixel_mm or 0.0,
            origin_px=tuple(args.origin_px) if args.origin_px else None,
            region=region,
            dark=args.dark,
            anchor_order=args.anchor_order,
            order_at=[tuple(p) for p in args.order_at or []],
            fringe_value_N_per_m=args.f_sigma_N_per_m,
            thickness_mm=args.thickness_mm,
            options=options[method](),
        )
        an.write(work, line=tuple(args.line) if args.line else None, points=args.points)
    summary = an.summary
    if not args.quiet:
        rng = summary["fringe_order_range"]
        print(
            f"fringekit analyze ({summary['method']}): {summary['valid_pixels']} valid, "
            f"{summary['reliable_pixels']} reliable pixels; fringe order "
            + (f"{rng[0]:.2f}..{rng[1]:.2f}" if rng else "none")
            + f"; results in {out}/"
        )
    if "warning" in summary:
        print(f"fringekit analyze: warning: {summary['warning']}", file=sys.stderr)
        if args.strict:
            return 1
    return 0
