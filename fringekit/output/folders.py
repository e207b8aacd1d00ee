"""Output folders: which folder a run may write, and how it replaces an earlier run.

Every command that writes a folder claims it with :func:`claim_output`:

- a missing or empty folder is used;
- a folder that holds an earlier run of the same command (its marker file
  :data:`MARKER`, and nothing the run did not write) is replaced, or, for the commands
  that resume (``sweep``, ``library build``), resumed;
- anything else is refused with one :class:`~fringekit.errors.InputError` line before any
  work: a file, a folder with files fringekit did not write, a run of another command, a
  folder that is or holds an input of the run or the current directory.

One run writes a folder at a time: the claim holds the lock file ``.<name>.lock`` beside
it (the pid of its run; the lock of a run that no longer lives is taken over). A run
writes into the hidden ``.<name>.<pid>-<hex>.part`` beside the folder and swaps it in
when it ends, so a failed or interrupted run leaves an earlier result as it was; what a
killed run leaves beside the folder is removed by the next run into it.
:func:`atomic_write` writes one file whole or not at all.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import sys
import time
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path

from fringekit.errors import InputError
from fringekit.output.versions import package_version

__all__ = [
    "MARKER",
    "OutputClaim",
    "as_paths",
    "atomic_write",
    "claim_output",
    "os_error_message",
]

#: The file in every output folder that says which command's run wrote it.
MARKER = ".fringekit-run.json"


def as_paths(value) -> list:
    """An option that takes one path or several, as a list (None: empty).

    Examples
    --------
    >>> as_paths("rest.png"), as_paths(["a.png", "b.png"]), as_paths(None)
    (['rest.png'], ['a.png', 'b.png'], [])
    """
    if value is None:
        return []
    return [value] if isinstance(value, (str, os.PathLike)) else list(value)


def atomic_write(path, data: str | bytes | Callable[[Path], object]) -> Path:
    """Write ``path`` whole or not at all: ``data`` (text or bytes), or ``data(tmp)``, a
    callable that writes the file it is given (same suffix), renamed to ``path`` when done."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}-{uuid.uuid4().hex[:8]}.part{path.suffix}")
    try:
        if callable(data):
            data(tmp)
        elif isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            tmp.write_text(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def claim_output(
    out,
    *,
    command: str,
    inputs: Iterable = (),
    resume: bool = False,
    option: str = "--out",
    say: Callable[[str], None] | None = None,
) -> OutputClaim:
    """``with claim_output(out, command="predict", inputs=[config]) as work:`` write the
    run into ``work``; it replaces ``out`` when the block ends normally and is removed
    when it raises (see the module doc). ``inputs`` are the paths the run reads (names
    that are no path, such as a built-in case, are ignored); ``resume`` writes into
    ``out`` itself; ``option`` names ``out`` in messages; ``say`` gets the line about
    removed leftovers of killed runs (default stderr)."""
    return OutputClaim(out, command, inputs, resume, option, say)


class OutputClaim:
    """A claimed output folder (:func:`claim_output`); a context manager whose value is
    the folder to write. ``dest`` is where the run went once the block has ended."""

    def __init__(self, out, command, inputs, resume, option, say):
        self.given, self.command, self.resume, self.option = str(out), command, resume, option
        self.out = self.dest = Path(out).resolve()
        self.inputs = [p for p in map(Path, filter(None, inputs)) if p.exists()]
        self.say = say or (lambda line: print(line, file=sys.stderr))
        self.lock = self.out.with_name(f".{self.out.name}.lock")
        self.work: Path | None = None
        self.earlier = False  # out holds an earlier run of the command

    def divert(self, suffix: str) -> None:
        """Send this run to ``<out>-<suffix>`` when ``out`` holds an earlier run (kept):
        predict's failed and interrupted runs."""
        if self.earlier:
            self.dest = self.out.with_name(f"{self.out.name}-{suffix}")

    def __enter__(self) -> Path:
        self._refuse(self.out)
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self._take_lock()
        try:
            self._refuse(self.out)  # again: it is ours now, nobody else changes it
            self.earlier = (self.out / MARKER).is_file()
            self._remove_leftovers()
            if self.resume:  # marked from the start: a killed run's folder is resumed
                self.out.mkdir(exist_ok=True)
                self.work = self.out
                if not self.earlier:
                    _mark(self.out, self.command, files=None)
            else:
                self.work = self.out.with_name(f".{self.out.name}.{_tag()}.part")
                self.work.mkdir()
        except BaseException:
            self.lock.unlink(missing_ok=True)
            raise
        return self.work

    def __exit__(self, kind, exc, tb) -> None:
        try:
            if kind is not None and not self.resume:
                shutil.rmtree(self.work, ignore_errors=True)
            elif not self.resume:
                _mark(self.work, self.command, files=_listing(self.work))
                self._swap_in()
        finally:
            self.lock.unlink(missing_ok=True)

    # -- what may be written ------------------------------------------------------------
    def _refuse(self, folder: Path) -> None:
        why = self._problem(folder)
        if why:
            raise InputError(
                f"{self.option} {self.given} {why}; give an empty or new folder, or a folder "
                f"of an earlier `fringekit {self.command}` run"
            )

    def _problem(self, folder: Path) -> str | None:
        """Why this run may not write ``folder``, or None."""
        if folder.exists() and not folder.is_dir():
            return "is a file"
        cwd = Path.cwd().resolve()
        if folder == cwd or folder in cwd.parents:
            return "is the current directory" if folder == cwd else "holds the current directory"
        for p in self.inputs:
            r = p.resolve()
            if folder == r or folder in r.parents:
                return f"{'is' if folder == r else 'holds'} {p}, an input of this run"
        if not folder.is_dir() or not any(folder.iterdir()):
            return None
        mark = _read_mark(folder)
        if mark is None:
            for up in folder.parents:
                if (up / MARKER).is_file():
                    other = (_read_mark(up) or {}).get("command", "?")
                    return f"is part of an earlier `fringekit {other}` run ({up})"
            return f"holds files fringekit did not write ({_names(_foreign(folder, set()))})"
        if mark.get("command") != self.command:
            return f"holds an earlier `fringekit {mark.get('command')}` run"
        extra = [] if self.resume else _foreign(folder, set(mark.get("files") or ()))
        if extra:
            return (
                f"holds an earlier `fringekit {self.command}` run and files it did not "
                f"write ({_names(extra)})"
            )
        return None

    # -- one writer at a time -----------------------------------------------------------
    def _take_lock(self) -> None:
        for _ in range(3):
            try:
                fd = os.open(self.lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                pid = _lock_pid(self.lock)
                if pid == 0:
                    continue  # released meanwhile
                if pid is None or _alive(pid):
                    who = f"pid {pid}" if pid else "an unreadable lock"
                    raise InputError(
                        f"{self.option} {self.given} is being written by another run ({who}; "
                        f"lock file {self.lock}); wait for it to end, or give another folder "
                        "(remove the lock file only if no such run is alive)"
                    ) from None
                if _lock_pid(self.lock) == pid:  # a killed run's lock: take it over
                    self.lock.unlink(missing_ok=True)
                continue
            with os.fdopen(fd, "w") as f:
                f.write(f"{os.getpid()}\n")
            return
        raise InputError(
            f"{self.option} {self.given}: could not take the lock file {self.lock}; try again"
        )

    def _remove_leftovers(self) -> None:
        """Remove the run folders of killed runs (``.<name>.<pid>-<hex>.part``, and the
        moved-aside ``.old`` of an earlier run) whose pid no longer lives."""
        pat = re.compile(rf"\.{re.escape(self.out.name)}\.(\d+)-[0-9a-f]+\.(part|old)")
        gone = []
        for p in sorted(self.out.parent.iterdir()):
            m = pat.fullmatch(p.name)
            if m and not _alive(int(m[1])):
                shutil.rmtree(p, ignore_errors=True)
                gone.append(p.name)
        if gone:
            self.say(
                f"fringekit: removed {len(gone)} unfinished folder(s) of killed runs "
                f"beside {self.given}: {', '.join(gone)}"
            )

    # -- the swap -----------------------------------------------------------------------
    def _swap_in(self) -> None:
        dest = self._free(self.dest)  # checked again: what was added meanwhile is kept
        if dest != self.dest == self.out:
            self.say(
                f"fringekit: {self.option} {self.given} changed during the run "
                f"({self._problem(self.out)}); this run is in {dest}"
            )
        if dest.is_dir() and any(dest.iterdir()):  # an earlier run (checked): aside, delete
            old = dest.with_name(f".{dest.name}.{_tag()}.old")
            os.replace(dest, old)
            os.replace(self.work, dest)
            shutil.rmtree(old, ignore_errors=True)
        else:  # missing or empty (a rename never replaces a folder that holds anything)
            os.replace(self.work, dest)
        self.dest = dest

    def _free(self, dest: Path) -> Path:
        """``dest``, or ``dest-2``, ``dest-3``... : the first this run may write."""
        k, path = 1, dest
        while self._problem(path) or (path != dest and path.exists()):
            k += 1
            path = dest.with_name(f"{dest.name}-{k}")
        return path


#: A run's hidden working name: ``.<name>.<pid>-<hex>.part`` (a folder) or
#: ``.<stem>.<pid>-<hex>.part<suffix>`` (a file of :func:`atomic_write`).
_WORKING = re.compile(r"\.([^/\\]+?)\.\d+-[0-9a-f]{8}\.part(\.[^/\\]*)?(?=$|[/\\])")


def os_error_message(exc: OSError) -> str:
    """An operating-system error as one line a user can act on: the path the user will
    see (a run's hidden working folders and files named by their final names), without
    the errno number.

    Examples
    --------
    >>> exc = PermissionError(13, "Permission denied", "/data/.out.4711-0a1b2c3d.part/maps.npz")
    >>> os_error_message(exc)
    '/data/out/maps.npz: Permission denied'
    >>> os_error_message(OSError(28, "No space left on device"))
    'No space left on device'
    """
    what = exc.strerror or str(exc)
    if exc.filename is None:
        return what
    path = _WORKING.sub(lambda m: m.group(1) + (m.group(2) or ""), os.fspath(exc.filename))
    return f"{path}: {what}"


def _tag() -> str:
    return f"{os.getpid()}-{uuid.uuid4().hex[:8]}"


def _mark(folder: Path, command: str, files) -> None:
    mark = {
        "command": command,
        "fringekit": package_version("fringekit", missing="0+unknown"),
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "files": files,
    }
    atomic_write(folder / MARKER, json.dumps(mark, indent=1))


def _read_mark(folder: Path) -> dict | None:
    try:
        mark = json.loads((folder / MARKER).read_text())
    except (OSError, ValueError):
        return None
    return mark if isinstance(mark, dict) else None


def _listing(folder: Path) -> list[str]:
    """Every file and folder (``name/``) under ``folder``, relative."""
    return sorted(
        p.relative_to(folder).as_posix() + ("/" if p.is_dir() else "") for p in folder.rglob("*")
    )


def _foreign(folder: Path, known: set) -> list[str]:
    """What ``folder`` holds beyond ``known`` (a :func:`_listing`): the outermost entries."""
    extra, todo = [], [folder]
    while todo:
        for p in sorted(todo.pop().iterdir()):
            rel = p.relative_to(folder).as_posix() + ("/" if p.is_dir() else "")
            if rel == MARKER:
                continue
            if rel not in known:
                extra.append(rel)
            elif p.is_dir():
                todo.append(p)
    return sorted(extra)


def _names(entries: list[str], shown: int = 4) -> str:
    more = len(entries) - shown
    return ", ".join(entries[:shown]) + (f" and {more} more" if more > 0 else "")


def _lock_pid(lock: Path) -> int | None:
    """The pid in a lock file; 0 when it is gone, None when it is unreadable."""
    try:
        return int(lock.read_text().strip())
    except FileNotFoundError:
        return 0
    except (OSError, ValueError):
        return None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` still runs. A killed run's process can linger as a zombie
    until it is reaped (in a container whose first process reaps nothing, for good):
    signal 0 still reaches it, so on Linux its state in /proc decides."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return not _zombie(pid)


def _zombie(pid: int) -> bool:
    """Whether ``pid`` has ended but not been reaped (state Z or X in /proc/PID/stat, the
    field after the command name's closing parenthesis); False where /proc is absent."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2 : stat.rfind(")") + 3] in ("Z", "X")
