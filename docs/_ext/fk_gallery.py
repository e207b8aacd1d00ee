"""sphinx-gallery hooks: run each example on its small test block and show its figures.

The examples of ``examples/`` are command-line scripts: they parse their options, write
their figures (PNG) and numbers (JSON) into an output folder and close their figures.
sphinx-gallery runs a script in its own namespace with no arguments and shows the figures
left open, so two hooks adapt it:

- :func:`example_argv` gives every example ``--coarse`` (the 12 x 12 mm test block of
  ``tests/test_examples.py``: seconds per example instead of minutes) and an output folder
  under ``docs/_build/gallery-out/`` (git-ignored; nothing is written into the
  repository), and hands the example its module docstring back (its ``--help`` text is the
  docstring's first line; sphinx-gallery blanks ``__doc__`` in the namespace it runs in);
- :func:`png_scraper` shows the PNG files the example wrote at the top of its output
  folder (the figures; the predict folders below it are left out);
- :func:`settle_progress_bars` keeps of the progress bars in an example's captured output
  only what a terminal would show when it ends (sphinx-gallery records every redraw).
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

from sphinx_gallery.scrapers import figure_rst

DOCS = Path(__file__).resolve().parents[1]
#: Where the gallery's examples write (one folder per example); git-ignored.
OUT = DOCS / "_build" / "gallery-out"


def output_folder(src_file: str | Path) -> Path:
    """The output folder of the example ``src_file`` during the docs build."""
    return OUT / Path(src_file).stem


def example_argv(gallery_conf: dict, script_vars: dict) -> list[str]:
    """Command-line arguments of an example run by the gallery (``reset_argv``)."""
    src = Path(script_vars["src_file"])
    out = output_folder(src)
    if out.exists():
        shutil.rmtree(out)  # so that the scraper shows only what this run wrote
    doc = ast.get_docstring(ast.parse(src.read_text(encoding="utf-8")), clean=False)
    script_vars["example_globals"]["__doc__"] = doc
    return ["--coarse", "--out", str(out)]


def png_scraper(block, block_vars: dict, gallery_conf: dict) -> str:
    """The PNG figures at the top of the example's output folder (or, when it has none,
    those one folder down: a command's own output folder), as reST images."""
    out = output_folder(block_vars["src_file"])
    pngs = (sorted(out.glob("*.png")) or sorted(out.glob("*/*.png"))) if out.is_dir() else []
    shown = []
    for png, dest in zip(pngs, block_vars["image_path_iterator"], strict=False):
        shutil.copyfile(png, dest)
        shown.append(dest)
    return figure_rst(shown, gallery_conf["src_dir"]) if shown else ""


def settle_progress_bars(app) -> None:
    """Rewrite the gallery's pages with every output line that carriage returns redraw
    (tqdm's bars) cut to its last non-blank state, or dropped when the bar cleared itself.
    Connected to ``builder-inited`` after sphinx-gallery has written the pages."""
    gallery = Path(app.srcdir) / app.config.sphinx_gallery_conf["gallery_dirs"]
    for page in gallery.glob("*.rst"):
        with open(page, encoding="utf-8", newline="") as fh:
            text = fh.read()
        if "\r" not in text:
            continue
        lines = []
        for line in text.split("\n"):
            if "\r" in line:
                drawn = [part for part in line.split("\r") if part.strip()]
                if not drawn:
                    continue
                line = drawn[-1]
            lines.append(line)
        with open(page, "w", encoding="utf-8", newline="") as fh:
            fh.write("\n".join(lines))


class PaperOrder:
    """Gallery order (``within_subsection_order``): the seed paper's figures in order, then
    the load calibration; as in ``examples/README.md``."""

    ORDER = (
        "fig3_white_light.py",
        "fig6_rgb_calibration.py",
        "fig7_phasemaps_misalignment.py",
        "fig8_axis_insensitive.py",
        "fig9_unwrapped.py",
        "fig10_11_foot.py",
        "calibration_load_to_fringe.py",
    )

    def __init__(self, src_dir: str):
        self.src_dir = src_dir

    def __call__(self, filename: str) -> tuple[int, str]:
        name = Path(filename).name
        return (self.ORDER.index(name) if name in self.ORDER else len(self.ORDER), name)

    def __repr__(self) -> str:
        return f"<{type(self).__name__}>"
