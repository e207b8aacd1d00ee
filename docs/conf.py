"""Sphinx configuration of the fringekit documentation.

Build (nothing is downloaded; the gallery runs every example on its small test block):

    python -m sphinx -W --keep-going -b html docs docs/_build/html

The API reference is generated from ``__all__``: :func:`write_api_pages` writes one page
per documented module into ``docs/api/`` with an autosummary table of its public names,
and autosummary writes a page per name into ``docs/api/generated/`` (both git-ignored).
"""

from __future__ import annotations

import importlib
import inspect
import re
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
# Document the checkout the docs belong to (its fringekit/__init__.py serves the stages'
# top-level folders), and find the gallery hooks in docs/_ext.
sys.path[:0] = [str(ROOT), str(DOCS / "_ext")]

import fringekit  # noqa: E402

project = "fringekit"
author = "the fringekit authors"
copyright = "the fringekit authors, BSD-3-Clause"
release = fringekit.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.viewcode",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "_templates"]
templates_path = ["_templates"]
# No intersphinx: the build must not fetch anything.

# -- Markdown (the explanation pages stay Markdown) --------------------------------------
myst_heading_anchors = 3
myst_enable_extensions = ["deflist"]

# -- API reference: one page per module, generated from its __all__ -----------------------
#: The modules whose ``__all__`` the reference documents, with a line on each.
API_MODULES = {
    "fringekit": "the application: configs, predict, analyse, calibrate, libraries, invert, track",
    "fringekit.meshes": "stage 1: sensor geometry and quadratic tetrahedral meshes",
    "fringekit.fea": "stage 2: hyperelastic contact solver",
    "fringekit.optics": "stage 3: through-thickness optics, polariscopes, light and camera",
    "fringekit.analysis": "image analysis: fringe images to fringe order and stress",
    "fringekit.tracking": "streams: every contact's load through a video, frames or a camera",
    "fringekit.sensor": "a library calibrated to one sensor: scales, camera, light, geometry",
}
GROUPS = ("Functions", "Classes", "Exceptions", "Data")


def _group(obj) -> str:
    if inspect.isclass(obj):
        return "Exceptions" if issubclass(obj, BaseException) else "Classes"
    return "Functions" if callable(obj) else "Data"


def _api_page(name: str, blurb: str) -> str:
    module = importlib.import_module(name)
    top = importlib.import_module("fringekit")
    public = [n for n in module.__all__ if not n.startswith("__")]
    if name != "fringekit":  # a name the top level exports is documented there, once
        public = [n for n in public if getattr(top, n, None) is not getattr(module, n)]
    lines = [f"``{name}``", "=" * (len(name) + 4), "", f"*{blurb.capitalize()}.*", ""]
    lines += [f".. automodule:: {name}", "   :no-members:", "", f".. currentmodule:: {name}", ""]
    for group in GROUPS:
        names = [n for n in public if _group(getattr(module, n)) == group]
        if names:
            lines += [group, "-" * len(group), "", ".. autosummary::", "   :toctree: generated"]
            lines += ["   :nosignatures:", "", *(f"   {n}" for n in names), ""]
    return "\n".join(lines)


def write_api_pages() -> None:
    """Write ``api/<module>.rst`` for every module of :data:`API_MODULES` from its
    ``__all__``, and drop the per-name pages of an earlier build (names may have gone)."""
    shutil.rmtree(DOCS / "api" / "generated", ignore_errors=True)
    for name, blurb in API_MODULES.items():
        page = DOCS / "api" / f"{name}.rst"
        text = _api_page(name, blurb)
        if not page.is_file() or page.read_text() != text:
            page.write_text(text)


write_api_pages()
autosummary_generate = True
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "signature"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- Gallery: examples/ run on their small test block (docs/_ext/fk_gallery.py) -----------
sphinx_gallery_conf = {
    "examples_dirs": "../examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/(fig\d|calibration)",  # every example (each on its test block)
    "ignore_pattern": r"(^|/)(common|__init__)\.py$",
    "reset_argv": "fk_gallery.example_argv",
    "image_scrapers": ("matplotlib", "fk_gallery.png_scraper"),
    "within_subsection_order": "fk_gallery.PaperOrder",
    "download_all_examples": False,
    "remove_config_comments": True,
    "min_reported_time": 1,
    "write_computation_times": False,  # its page loads scripts from the web
}

# -- HTML -------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"fringekit {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_static_path: list[str] = []
html_show_sourcelink = False


# -- Hooks ------------------------------------------------------------------------------
#: Links of the Markdown pages to files outside docs/ that have a page here (the pages are
#: written to read well on GitHub too).
OUTSIDE_LINKS = {"../examples/README.md": "paper.md", "../README.md": "index.md"}
#: ``|expr|`` in a docstring's prose is an absolute value, not a reST substitution.
BARS = re.compile(r"(``.*?``)|\|")


def _link_outside_pages(app, docname: str, source: list[str]) -> None:
    for outside, page in OUTSIDE_LINKS.items():
        source[0] = source[0].replace(f"]({outside})", f"]({page})")


def _escape_bars(app, what, name, obj, options, lines: list[str]) -> None:
    doctest = False  # a doctest block runs from a ">>>" line to the next blank line
    for i, line in enumerate(lines):
        text = line.strip()
        doctest = text.startswith(">>>") or (doctest and bool(text))
        table_row = text.startswith("|") and text.endswith("|")  # or a line block:
        if "|" in text and not (doctest or table_row or text.startswith("| ")):
            lines[i] = BARS.sub(lambda m: m.group(1) or "\\|", line)


def setup(app):
    import fk_gallery

    app.connect("builder-inited", fk_gallery.settle_progress_bars, priority=600)  # after it
    app.connect("source-read", _link_outside_pages)
    app.connect("autodoc-process-docstring", _escape_bars, priority=400)  # before numpydoc
