"""On-disk mesh cache keyed by a hash of the mesh inputs."""

from __future__ import annotations

import logging
import os
import zipfile
from importlib.metadata import version
from pathlib import Path

import platformdirs

from .build import MESHER_VERSION, mesh_uncached
from .io import load_npz, save_npz
from .mesh import Mesh
from .spec import MeshSpec

__all__ = ["default_cache_dir", "build_mesh", "cache_path", "UNREADABLE"]

log = logging.getLogger("fringekit.meshes")

#: What reading a damaged cache file raises (truncated zip, empty file, missing arrays).
UNREADABLE = (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile)


def default_cache_dir() -> Path:
    """``$FRINGEKIT_CACHE_DIR`` if set, else the user cache directory + ``fringekit``."""
    env = os.environ.get("FRINGEKIT_CACHE_DIR")
    if env:
        return Path(env)

    return Path(platformdirs.user_cache_dir("fringekit"))


def _salt(spec: MeshSpec) -> str:
    """The versions the mesh of ``spec`` depends on (part of its cache key)."""
    libs = ("numpy", "scipy") if spec.mesher == "layered" else ("pytetwild",)
    return f"mesher={MESHER_VERSION};" + ";".join(f"{n}={version(n)}" for n in libs)


def cache_path(spec: MeshSpec, cache_dir: str | os.PathLike | None = None) -> Path:
    """Where the mesh of ``spec`` is (or would be) cached."""
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return root / "meshes" / f"{spec.key(_salt(spec))[:32]}.npz"


def build_mesh(
    spec: MeshSpec | None = None,
    *,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    num_threads: int = 0,
) -> Mesh:
    """Return the mesh for ``spec``, from the cache when it is there.

    Parameters
    ----------
    spec : MeshSpec, optional
        Mesh inputs; default: the reference case (3 mm sheet on 15 mm polycarbonate,
        40 x 40 mm, one 3.5 mm indenter at the centre, full model).
    cache_dir : path, optional
        Cache root; default :func:`default_cache_dir`.
    use_cache : bool
        False always regenerates (and does not write the cache).
    num_threads : int
        fTetWild threads; 0 uses all cores.
    """
    spec = MeshSpec() if spec is None else spec
    path = cache_path(spec, cache_dir)
    if use_cache and path.exists():
        try:
            mesh = load_npz(path)
            log.info("mesh cache hit: %s", path)
            return mesh
        except UNREADABLE as exc:  # truncated, empty or foreign: mesh again, overwrite it
            log.warning("mesh cache %s is unreadable (%s); meshing again", path, exc)
    mesh = mesh_uncached(spec, num_threads=num_threads)
    if use_cache:
        save_npz(mesh, path)
        log.info("mesh cached: %s", path)
    return mesh
