"""The README's and the docs' Python blocks run as written, after the README's first command.

The blocks are taken from README.md and from the docs pages that show code to copy
(``docs/getting-started.md``, ``docs/stages.md``) as they stand, and executed in order,
one namespace per page, in a scratch folder where ``fringekit predict`` has just written
``fringekit-out/reference`` (the session's cache keeps the meshes; nothing else is
changed). The README's first screen and its shell commands are checked as text: the two
fresh-machine commands come first and exactly as given, and no command writes into the
repository's root (outputs go under the git-ignored ``fringekit-out/``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fringekit.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = ("README.md", "docs/getting-started.md", "docs/stages.md")
BLOCKS = [
    (page, k, code)
    for page in PAGES
    for k, code in enumerate(re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), re.S))
]
FRESH_MACHINE = [
    "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/fringekit predict\n",
    "python3 -m venv .venv && .venv/bin/pip install '.[test]' && .venv/bin/python -m pytest\n",
]
README_PYTHON = """\
import fringekit

config = fringekit.Config.reference().replace({"optics.pixels": 96, "optics.samples_per_ray": 24})
prediction = fringekit.predict(config)
print(prediction.states[-1].max_fringe_order)
prediction.write("fringekit-out/python-example")
"""


def _fenced(text: str) -> list[tuple[str, str]]:
    return re.findall(r"```(\w*)\n(.*?)```", text, re.S)


def test_the_readme_starts_with_the_two_fresh_machine_commands():
    blocks = _fenced(README.read_text())
    assert [code for _, code in blocks[:2]] == FRESH_MACHINE
    assert blocks[0][0] == blocks[1][0] == "bash"


def test_the_readme_has_its_python_block_and_the_docs_have_theirs():
    assert [code for page, _, code in BLOCKS if page == "README.md"] == [README_PYTHON]
    for page in PAGES[1:]:
        assert any(p == page for p, _, _ in BLOCKS), page


def _outputs(command: str) -> list[str]:
    """The paths a shell command of the README writes: ``--out X`` and ``> X``."""
    return re.findall(r"--out\s+(\S+)", command) + re.findall(r"(?<!-)>\s*(\S+)", command)


def test_readme_commands_write_nothing_into_the_repository_root():
    shell = [code for lang, code in _fenced(README.read_text()) if lang in ("bash", "text")]
    lines = [c for code in shell for c in code.replace("\\\n", " ").splitlines()]
    commands = [re.sub(r"\s#.*$", "", c) for c in lines]  # without their comments
    assert any("--out" in c for c in commands)
    outputs = [(c, p) for c in commands for p in _outputs(c)]
    wrong = [(c, p) for c, p in outputs if not p.startswith(("fringekit-out/", "docs/_build/"))]
    assert not wrong, wrong
    python_outputs = re.findall(r"\.write\(\"([^\"]+)\"\)", README_PYTHON)
    assert python_outputs and all(p.startswith("fringekit-out/") for p in python_outputs)


@pytest.fixture(scope="module")
def after_first_command(tmp_path_factory, cache_dir):
    root = tmp_path_factory.mktemp("readme")
    mp = pytest.MonkeyPatch()
    mp.chdir(root)
    mp.setenv("FRINGEKIT_CACHE_DIR", str(cache_dir))
    assert main(["predict", "--quiet"]) == 0  # the first command's job
    yield root
    mp.undo()


NAMESPACES: dict[str, dict] = {}


@pytest.mark.parametrize(("page", "k"), [(page, k) for page, k, _ in BLOCKS])
def test_python_block_runs_as_written(after_first_command, page, k):
    code = next(c for p, j, c in BLOCKS if (p, j) == (page, k))
    namespace = NAMESPACES.setdefault(page, {"__name__": f"{Path(page).stem}_blocks"})
    exec(compile(code, f"{page} python block {k + 1}", "exec"), namespace)
