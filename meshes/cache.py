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
    """Where meshes (and other fringekit caches) are kept.

    Returns
    -------
    pathlib.Path
        ``$FRINGEKIT_CACHE_DIR`` if set, else the user cache directory (platformdirs) +
        ``fringekit``.

    Examples
    --------
    >>> import os
    >>> from fringekit.meshes import default_cache_dir
    >>> before = os.environ.get("FRINGEKIT_CACHE_DIR")
    >>> os.environ["FRINGEKIT_CACHE_DIR"] = "/tmp/fk-cache"
    >>> str(default_cache_dir())
    '/tmp/fk-cache'
    >>> if before is None:
    ...     del os.environ["FRINGEKIT_CACHE_DIR"]
    ... else:
    ...     os.environ["FRINGEKIT_CACHE_DIR"] = before
    """
    env = os.environ.get("FRINGEKIT_CACHE_DIR")
    if env:
        return Path(env)

    return Path(platformdirs.user_cache_dir("fringekit"))


def _salt(spec: MeshSpec) -> str:
    """The versions the mesh of ``spec`` depends on (part of its cache key)."""
    libs = ("numpy", "scipy") if spec.mesher == "layered" else ("pytetwild",)
    return f"mesher={MESHER_VERSION};" + ";".join(f"{n}={version(n)}" for n in libs)


def cache_path(spec: MeshSpec, cache_dir: str | os.PathLike | None = None) -> Path:
    """Where the mesh of ``spec`` is (or would be) cached.

    The file name is a hash of the spec and of the versions of the mesher and of the
    libraries its output depends on.

    Parameters
    ----------
    spec : MeshSpec
    cache_dir : path, optional
        Cache root; default :func:`default_cache_dir`.

    Returns
    -------
    pathlib.Path
        ``<cache_dir>/meshes/<hash>.npz``.

    Examples
    --------
    >>> from fringekit.meshes import MeshSpec, cache_path
    >>> p = cache_path(MeshSpec(), "/tmp/cache")
    >>> p.parent.as_posix(), p.suffix, len(p.stem)
    ('/tmp/cache/meshes', '.npz', 32)
    """
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return root / "meshes" / f"{spec.key(_salt(spec))[:32]}.npz"


def build_mesh(
    spec: MeshSpec | None = None,
    *,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    num_threads: int = 0,
) -> Mesh:
    """The mesh of ``spec``: from the cache when it is there, else meshed and cached.

    The one way to a mesh. With the default ``spec.mesher = "layered"`` the mesh depends
    only on ``spec`` (and the numpy and scipy versions), bit for bit.

    Parameters
    ----------
    spec : MeshSpec, optional
        Mesh inputs; default: the reference case (3 mm sheet on 15 mm polycarbonate,
        40 x 40 mm, one 3.5 mm indenter at the centre, full model).
    cache_dir : path, optional
        Cache root; default :func:`default_cache_dir`.
    use_cache : bool
        False meshes again and neither reads nor writes the cache.
    num_threads : int
        fTetWild threads (``mesher = "tetwild"`` only); 0 uses all cores.

    Returns
    -------
    Mesh
        Points (m), 10-node tets, region per cell and the facet sets ``contact``,
        ``interface`` (empty for a single sheet), ``bottom``, ``sides`` and the
        symmetry planes of the model.

    Raises
    ------
    MeshQualityError
        If the tets cannot be put onto the exact geometry or contain inverted or
        degenerate cells.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> mesh.n_points, mesh.n_cells
    (245, 108)

    Cached in a folder of your choice (a damaged cache file is meshed again):

    >>> import tempfile
    >>> from fringekit.meshes import cache_path
    >>> with tempfile.TemporaryDirectory() as d:
    ...     cached = build_mesh(spec, cache_dir=d)
    ...     print(cache_path(spec, d).is_file(), build_mesh(spec, cache_dir=d).same_as(mesh))
    True True
    """
    spec = MeshSpec() if spec is None else spec
    path = cache_path(spec, cache_dir)
    if use_cache and path.exists():
        try:
            mesh = load_npz(path)
            if mesh.spec is not None and mesh.spec.to_dict() == spec.to_dict():
                log.info("mesh cache hit: %s", path)
                return mesh
            # another spec's mesh under this name (a copied or renamed file): mesh again
            log.warning("mesh cache %s holds the mesh of another spec; meshing again", path)
        except UNREADABLE as exc:  # truncated, empty or foreign: mesh again, overwrite it
            log.warning("mesh cache %s is unreadable (%s); meshing again", path, exc)
    mesh = mesh_uncached(spec, num_threads=num_threads)
    if use_cache:
        save_npz(mesh, path)
        log.info("mesh cached: %s", path)
    return mesh
