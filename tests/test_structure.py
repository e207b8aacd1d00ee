"""The code-base rules a newcomer relies on, checked rather than hoped for.

Module and function sizes, public names across modules, no plotting-backend switches in
library code, and documentation that stays inside the repository. The one-way layering of
the packages is checked by import-linter (``pyproject.toml``, run by ``.ci/run``).
"""

from __future__ import annotations

import ast
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("meshes", "fea", "optics", "analysis", "fringekit")
SOURCES = sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))
SCRIPTS = sorted([*(ROOT / "bench").glob("*.py"), *(ROOT / "examples").glob("*.py")])
TESTS = sorted((ROOT / "tests").glob("*.py"))


def _rel(p: Path) -> str:
    return str(p.relative_to(ROOT))


def _docstring_lines(node: ast.AST) -> set[int]:
    """The line numbers of the docstrings in ``node`` (its own and those of everything in
    it): documentation, with its examples, is not code."""
    lines: set[int] = set()
    for n in ast.walk(node):
        body = getattr(n, "body", None)
        if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and (
            body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
        ):
            if isinstance(body[0].value.value, str):
                lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    return lines


def test_packages_have_small_modules_and_functions():
    """At most 400 lines of code per module and 100 per function (docstrings not
    counted: the numpydoc sections and examples of a public name can be longer than it)."""
    long_modules, long_functions = [], []
    for p in SOURCES:
        tree = ast.parse(p.read_text())
        if (n := p.read_text().count("\n") - len(_docstring_lines(tree))) > 400:
            long_modules.append((_rel(p), n))
    for p in [*SOURCES, *SCRIPTS]:
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1 - len(_docstring_lines(node))
                if n > 100:
                    long_functions.append((_rel(p), node.name, n))
    assert not long_modules, long_modules
    assert not long_functions, long_functions


def test_no_private_name_is_imported_across_modules():
    found = []
    for p in [*SOURCES, *SCRIPTS, *TESTS]:
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom):
                for a in node.names:
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        found.append((_rel(p), node.module, a.name))
    assert not found, found


def test_library_code_never_switches_the_matplotlib_backend():
    found = [_rel(p) for p in SOURCES if re.search(r"matplotlib\.use\(", p.read_text())]
    assert not found, found


def _docs() -> list[Path]:
    return sorted(
        p
        for p in ROOT.rglob("*")
        if p.suffix in (".py", ".md", ".toml", ".cff")
        and not {".venv", ".git", "build", ".pytest_cache"} & set(p.relative_to(ROOT).parts)
        and p.name != "test_structure.py"
    )


def test_nothing_refers_to_files_outside_the_repository():
    outside = re.compile(r"\.\./" + "shared" + r"\b|DESIGN\.md|DEPENDENCIES\.md")
    found = [_rel(p) for p in _docs() if outside.search(p.read_text())]
    assert not found, found


DOC_PAGES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))


@pytest.mark.parametrize("doc", ["README.md", "examples/README.md", *DOC_PAGES])
def test_markdown_links_resolve_inside_the_repository(doc):
    path = ROOT / doc
    text = path.read_text()
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [x for x in links if not re.match(r"[a-z]+://", x)]
    missing = [x for x in local if not (path.parent / x).resolve().exists()]
    outside = [
        x
        for x in local
        if ROOT not in (path.parent / x).resolve().parents and (path.parent / x).resolve() != ROOT
    ]
    assert not missing and not outside, (missing, outside)


def _patched_names(tree: ast.AST) -> list[str]:
    """Dotted names a test module patches: ``monkeypatch.setattr(obj, "name", value)`` (the
    object's dotted source and the name), ``monkeypatch.setattr("pkg.mod.name", value)``,
    ``monkeypatch.delattr`` likewise, and ``mock.patch("pkg.mod.name")`` /
    ``patch.object(obj, "name")``."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        func, args = node.func, node.args
        attr = func.attr if isinstance(func, ast.Attribute) else None
        if isinstance(func, ast.Name) and func.id == "patch":
            attr = "patch"
        if attr in ("setattr", "delattr", "object") and args:
            if isinstance(args[0], ast.Constant) and isinstance(args[0].value, str):
                found.append(args[0].value)  # the "pkg.mod.name" form
            elif len(args) > 1 and isinstance(args[1], ast.Constant):
                found.append(f"{ast.unparse(args[0])}.{args[1].value}")
        elif attr == "patch" and args and isinstance(args[0], ast.Constant):
            found.append(str(args[0].value))
    return found


def test_no_test_patches_a_private_name():
    """Tests drive the code through public seams: a patched private function ties the
    test to an implementation detail that a refactoring may rename or inline, and the
    test then patches nothing and still passes. Patch a public name, or give the code an
    input that produces the behaviour."""
    sample = ast.parse('mp.setattr(fit, "_pick", f); mp.setattr("a._b.c", 1); patch("x.y")')
    assert _patched_names(sample) == ["fit._pick", "a._b.c", "x.y"]
    found = []
    for p in TESTS:
        for name in _patched_names(ast.parse(p.read_text())):
            private = [
                part
                for part in name.split(".")
                if part.startswith("_") and not part.startswith("__")
            ]
            if private:
                found.append((_rel(p), name))
    assert not found, found


def _module_name(path: Path) -> str:
    """The dotted name a source file installs as (the stages are mapped into fringekit)."""
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[0] != "fringekit":
        parts.insert(0, "fringekit")
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


#: Imports kept inside functions on purpose, each optional or heavy and needed on one path
#: only: PARDISO (x86 only), fTetWild (mesher = "tetwild"), Dask's cluster (sweeps and
#: library builds), VTK through pyvista (VTU files, FEM fields) and matplotlib.tri with it,
#: OpenCV (the optional extra fringekit[camera], for ``fringekit track camera:N`` only).
LAZY_IMPORTS = {
    "pypardiso",
    "pytetwild",
    "dask.distributed",
    "pyvista",
    "matplotlib.tri",
    "colour",
    "cv2",
    "matplotlib.pyplot",  # a window (track --show) picks a GUI backend: only when asked
}


def test_imports_sit_at_the_top_of_their_modules():
    found = []
    for p in SOURCES:
        for fn in ast.walk(ast.parse(p.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom):
                    names = [node.module or ""]
                else:
                    continue
                lazy = [n for n in names if n.split(".")[0] in LAZY_IMPORTS or n in LAZY_IMPORTS]
                found += [(_rel(p), fn.name, n) for n in names if n not in lazy]
    assert not found, found


def test_no_import_cycle_between_modules():
    """Module-level imports of fringekit's modules form no cycle (a package's __init__
    included: a module that imports its own package's __init__ while the __init__
    imports it is a cycle)."""
    modules = {_module_name(p): p for p in SOURCES}
    graph: dict[str, set[str]] = {}
    for name, p in modules.items():
        is_pkg = p.name == "__init__.py"
        edges = set()
        for node in ast.parse(p.read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.level:
                base = name.split(".")[: len(name.split(".")) - node.level + is_pkg]
                target = ".".join(base + ([node.module] if node.module else []))
            elif isinstance(node, ast.ImportFrom):
                target = node.module or ""
            elif isinstance(node, ast.Import):
                target = node.names[0].name
            else:
                continue
            if isinstance(node, ast.ImportFrom):
                subs = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in modules]
                edges.update(subs or [target])
            else:
                edges.add(target)
        graph[name] = {e for e in edges if e in modules and e != name}
    # the top-level package re-exports the API: edges into it are the interpreter's, not
    # a design choice, and fringekit itself is the root every import passes through
    graph.pop("fringekit", None)
    state: dict[str, int] = {}
    cycles = []

    def visit(n, path):
        state[n] = 1
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                cycles.append(path[path.index(m) :] + [m])
            elif m not in state:
                visit(m, [*path, m])
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n, [n])
    assert not cycles, cycles


@pytest.mark.parametrize("script", sorted((ROOT / "bench").glob("*.py")), ids=lambda p: p.name)
def test_every_bench_script_imports(script):
    """A benchmark imports what it measures by public names that exist (running one takes
    minutes; its imports are what a restructuring breaks)."""
    spec = importlib.util.spec_from_file_location(f"bench_{script.stem}", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert callable(module.main)


def test_the_formatter_is_never_switched_off():
    """The formatter's off switches hide code from ruff format (there were 294)."""
    switch = re.compile(r"#\s*fmt:\s*(skip|off)\b")
    files = [p for p in [*SOURCES, *SCRIPTS, *TESTS] if p.name != "test_structure.py"]
    found = [_rel(p) for p in files if switch.search(p.read_text())]
    assert not found, found
