"""The check every refusal test shares: a command given bad input exits 2 with one line on
stderr that names what the test asks for, shows no Python internals, and writes nothing."""

from __future__ import annotations

import re

from fringekit.cli import main

#: Python internals a user's message must not show: reprs, tracebacks, function names.
REPR = re.compile(r"np\.\w+\(|PosixPath\(|WindowsPath\(|Traceback|load_six_step|compare_maps")


def refused(argv, capsys, words, out) -> str:
    """Run ``fringekit argv``: exit 2, one line holding every one of ``words``, no
    :data:`REPR`, and ``out`` not created; the line."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    assert all(w in err for w in words), err
    assert not REPR.search(err), err
    assert not out.exists()
    return err
