"""Every Python block of the README runs as written, after the README's first command.

The blocks are taken from README.md as they stand and executed in order in a scratch
folder where ``fringekit predict`` has just written ``fringekit-out/reference`` (the
session's cache keeps the meshes; nothing else is changed)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fringekit.cli.main import main

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 4


@pytest.fixture(scope="module")
def after_first_command(tmp_path_factory, cache_dir):
    root = tmp_path_factory.mktemp("readme")
    mp = pytest.MonkeyPatch()
    mp.chdir(root)
    mp.setenv("FRINGEKIT_CACHE_DIR", str(cache_dir))
    assert main(["predict", "--quiet"]) == 0  # the first command's job
    yield root
    mp.undo()


@pytest.mark.parametrize("k", range(len(BLOCKS)))
def test_readme_python_block_runs_as_written(after_first_command, k):
    code = compile(BLOCKS[k], f"README.md python block {k + 1}", "exec")
    exec(code, {"__name__": f"readme_block_{k + 1}"})
