"""Every public name is documented with an example, and every example runs.

The examples in the docstrings are doctests: :func:`test_examples_run` runs those of every
module of the package (the application's sub-packages and the four pipeline stages), and
:func:`test_public_names_have_examples` checks that every name a user imports from
``fringekit`` or a stage has a numpydoc docstring with an ``Examples`` section (and, in the
stages, ``Parameters`` and ``Returns`` where the signature has them).
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest

import fringekit

#: The pipeline stages, mapped into the package from the repository's top-level folders.
STAGES = ("meshes", "fea", "optics", "analysis")

#: What may follow ``fringekit.``: the stages and the modules and packages in fringekit's own
#: folder. In a source checkout the checkout root is on ``fringekit.__path__`` (to serve the
#: stages), so it would also offer ``fringekit.fringekit`` (the package a second time) and
#: any other folder of the checkout as sub-packages.
KNOWN = frozenset(STAGES) | {
    m.name for m in pkgutil.iter_modules([Path(fringekit.__file__).parent])
}

#: Modules whose import has effects: ``python -m fringekit`` runs the command line.
NOT_IMPORTED = frozenset({"fringekit.__main__"})

#: Where the public names are: ``fringekit`` itself and the four stages.
PUBLIC = ("fringekit",) + tuple(f"fringekit.{s}" for s in STAGES)

#: Public names without an ``Examples`` section yet. Keep it short: a name that gains its
#: examples must leave this list (the test says so), and a new public name needs its own.
#: All of them are fringekit's own (the API); every name of the stages has examples.
NO_EXAMPLES_YET: frozenset[str] = frozenset()

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _modules() -> list[str]:
    """Every module of the package: ``pkgutil.walk_packages`` from each known entry of
    ``fringekit.__path__`` (the unknown ones are not imported), and fringekit itself."""
    names = ["fringekit"]
    for info in pkgutil.iter_modules(fringekit.__path__, "fringekit."):
        if info.name.split(".")[1] not in KNOWN or info.name in NOT_IMPORTED:
            continue
        names.append(info.name)
        if info.ispkg:
            path = importlib.import_module(info.name).__path__
            names += [m.name for m in pkgutil.walk_packages(path, info.name + ".")]
    return sorted(set(names) - NOT_IMPORTED)


MODULES = _modules()


@pytest.fixture
def numpy_printing():
    """numpy's own print options (not the 1.13 legacy mode colour-science switches on)
    while the examples run, and the caller's afterwards."""
    saved = np.get_printoptions()
    np.set_printoptions(legacy=False)
    try:
        yield
    finally:
        np.set_printoptions(**saved)


def test_the_walk_finds_the_stages_and_the_application():
    assert {"fringekit.meshes.spec", "fringekit.fea.solver", "fringekit.optics.jones"} <= set(
        MODULES
    )
    assert {"fringekit.analysis.unwrap", "fringekit.cli", "fringekit.config"} <= set(MODULES)
    assert not [m for m in MODULES[1:] if m.split(".")[1] not in KNOWN]
    assert MODULES[0] == "fringekit"


#: Modules whose examples take several seconds: those that build a response library (about
#: 20 s each on 2 cores), and the predict-then-analyze round trips of ``measurement.order``.
SLOW_EXAMPLES = frozenset(
    {
        "fringekit.measurement.order",
        "fringekit.inversion.loads",
        "fringekit.library.build",
        "fringekit.tracking.stream",
        "fringekit.sensor.calibrate",
    }
)


@pytest.mark.parametrize(
    "name",
    [pytest.param(m, marks=pytest.mark.slow) if m in SLOW_EXAMPLES else m for m in MODULES],
)
def test_examples_run(name, numpy_printing):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    report: list[str] = []
    for test in finder.find(module, name):
        runner.run(test, out=report.append)
    failed, _ = runner.summarize(verbose=False)
    assert failed == 0, "".join(report)


def _public_names():
    for pkg in PUBLIC:
        module = importlib.import_module(pkg)
        for name in module.__all__:
            if name != "__version__":
                yield pkg, name, getattr(module, name)


def _section(doc: str, title: str) -> bool:
    return re.search(rf"^\s*{title}\n\s*-{{{len(title)}}}\s*$", doc, re.MULTILINE) is not None


def _has_examples(doc: str | None) -> bool:
    return bool(doc) and _section(doc, "Examples") and ">>>" in doc


def _documented_constant(pkg: str, name: str) -> bool:
    """A module-level constant has a ``#:`` comment right above its assignment (Sphinx's
    attribute docstring) in a module of ``pkg``: a number or a tuple has no docstring."""
    top = importlib.import_module(pkg)
    mods = [pkg] + [m for m in MODULES if m.startswith(pkg + ".")]
    pattern = re.compile(rf"^{re.escape(name)}\s*(:[^=]*)?=", re.MULTILINE)
    for mod in mods if hasattr(top, "__path__") else [pkg]:
        source = inspect.getsource(importlib.import_module(mod))
        for match in pattern.finditer(source):
            before = source[: match.start()].rstrip("\n").rsplit("\n", 1)[-1]
            if before.startswith("#:"):
                return True
    return False


def _missing_sections(obj) -> list[str]:
    """The numpydoc sections a stage function or class lacks: ``Parameters`` when its
    signature takes any, ``Returns`` for a function (``None`` is said so too)."""
    doc = obj.__doc__ or ""
    missing = []
    if inspect.isclass(obj) and issubclass(obj, BaseException):
        return missing  # constructed with a message, raised by the stage
    try:
        params = [
            p for p in inspect.signature(obj).parameters.values() if p.name not in ("self", "cls")
        ]
    except (TypeError, ValueError):  # pragma: no cover (a builtin without a signature)
        params = []
    only_varargs = all(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params)
    if params and not (inspect.isclass(obj) and only_varargs) and not _section(doc, "Parameters"):
        missing.append("Parameters")
    if inspect.isroutine(obj) and not (_section(doc, "Returns") or _section(doc, "Yields")):
        missing.append("Returns")
    return missing


def test_public_names_have_examples():
    """Every name of ``fringekit.__all__`` and the stages' ``__all__``: classes and
    functions have a numpydoc ``Examples`` section (with ``Parameters`` and ``Returns`` in
    the stages), constants a ``#:`` comment."""
    missing, sections, constants = [], [], []
    for pkg, name, obj in _public_names():
        if inspect.isclass(obj) or inspect.isroutine(obj):
            if not _has_examples(obj.__doc__) and name not in NO_EXAMPLES_YET:
                missing.append(f"{pkg}.{name}")
            if pkg != "fringekit" and _missing_sections(obj):
                sections.append(f"{pkg}.{name}: {', '.join(_missing_sections(obj))}")
        elif not _documented_constant(pkg, name):
            constants.append(f"{pkg}.{name}")
    assert not missing, f"public names without an Examples section: {missing}"
    assert not sections, f"numpydoc sections missing: {sections}"
    assert not constants, f"constants without a '#:' comment above them: {constants}"


def test_the_allow_list_holds_only_names_still_without_examples():
    public = {name: obj for _, name, obj in _public_names()}
    unknown = sorted(NO_EXAMPLES_YET - set(public))
    done = sorted(n for n in NO_EXAMPLES_YET & set(public) if _has_examples(public[n].__doc__))
    assert not unknown, f"NO_EXAMPLES_YET names no public name: {unknown}"
    assert not done, f"these have examples now; remove them from NO_EXAMPLES_YET: {done}"


@pytest.mark.parametrize("name", MODULES)
def test_no_example_is_skipped(name):
    """An example a doctest skips is one nobody checks: every example runs (the slow
    ones in the slow tier)."""
    source = inspect.getsource(importlib.import_module(name))
    assert "doctest: +SKIP" not in source
