"""A response library: one sensor's single-indenter fields over a grid of loads.

Folder layout (written by :mod:`fringekit.library.build`)::

    manifest.json       format, sensor config, grid, lattice, mesh settings, versions,
                        the sha256 of every field file, and ``manifest_sha256``: the
                        sha256 of the manifest's own canonical JSON
                        (:func:`manifest_checksum`), so an edited grid or diameter is
                        refused like an edited field file
    config.toml         the sensor config the library was built for
    fields_dXXXX.npz    one per indenter diameter (XXXX = diameter in um):
                        AB (nF, nS, R, F, S, 2) float32  polar slab pairs (Pa m),
                        valid (nF, nS, R, F), contact_radius_m (nF, nS),
                        centre_m (nF, nS, 3) indenter centre relative to its first-touch
                        point, force_N (nF, nS, 3)

The grid is normal load ``load_N`` (nF, increasing) x tangential ratio ``shear_ratio``
(nS, from 0): the seed paper's protocol, normal load first, then tangential load at
constant normal load. Between grid points fields are interpolated linearly in load and
ratio (a zero-load field, no stress and no contact, is implied below the first load), and
bilinearly in (r, phi) on the lattice (:mod:`fringekit.library.lattice`). A tangential load in
any other direction is the +x solution turned about the axis.
"""

from __future__ import annotations

import hashlib
import json
from bisect import bisect_left
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from fringekit.errors import LibraryError
from fringekit.library.lattice import PolarLattice, interpolate_turned

__all__ = [
    "FIELD_KEYS",
    "FORMAT",
    "Library",
    "LibraryError",
    "LoadedIndenter",
    "check_sensor",
    "diameter_id",
    "field_file",
    "load_library",
    "manifest_checksum",
    "sensor_key",
    "sha256",
]

#: 2: the manifest holds a checksum of its own (1: of the field files only).
#: 3: under friction a point sticks where it first touches (fea.contact), so the
#: stick fields of earlier libraries depend on the load steps they were built with.
#: Older formats are refused with the command that rebuilds the library.
FORMAT = "fringekit-library/3"
#: Earlier formats -> why they are refused.
_OLD_FORMATS = {
    "fringekit-library/1": "its manifest.json has no checksum of its own, so edits to it "
    "go unnoticed",
    "fringekit-library/2": "its stick fields anchored each point where it was at the start "
    "of a load step, so they depend on the load steps (up to 2 % in load)",
}
#: The arrays of a field file (module docstring).
FIELD_KEYS = ("AB", "valid", "contact_radius_m", "centre_m", "force_N")


def diameter_id(diameter_mm: float) -> str:
    """The name part of one diameter's files and tasks: ``d`` and the diameter in um."""
    return f"d{int(round(diameter_mm * 1000)):05d}"


def field_file(diameter_mm: float) -> str:
    return f"fields_{diameter_id(diameter_mm)}.npz"


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def manifest_checksum(manifest: dict) -> str:
    """The sha256 of a manifest's canonical JSON (sorted keys, no spaces), leaving out its
    own ``manifest_sha256``: how it reads back from ``manifest.json``, whatever the
    layout of the file."""
    body = {k: v for k, v in manifest.items() if k != "manifest_sha256"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()


def sensor_key(cfg: dict) -> dict:
    """What makes two configs the same sensor for a library: the sheet, the substrate and
    the sheet's stress-optic law (not the camera, the loads or the friction: a library
    holds full-stick solutions)."""
    o = cfg["optics"]
    return {
        "sheet": dict(cfg["sheet"]),
        "substrate": dict(cfg["substrate"]),
        "optics": {
            k: o[k]
            for k in ("f_sigma_N_per_m", "wavelength_nm", "dispersion", "dispersion_coefficient")
        },
    }


@dataclass(frozen=True)
class LoadedIndenter:
    """One indenter to synthesise: position of its axis at first touch (m), sphere
    diameter (m) and the force it exerts on the sheet (N; Fz > 0 presses)."""

    x: float
    y: float
    diameter: float
    fx: float
    fy: float
    fz: float


def _weights(grid: np.ndarray, v: float) -> tuple[tuple[int, int], tuple[float, float]]:
    """Two node indices and linear weights of ``v`` on an increasing grid (clamped).

    In Python scalars (a bisection and min/max): numpy's searchsorted and clip cost 20
    times more on one value, and this runs twice per library state, thousands of times
    a second in a tracked stream."""
    i = min(max(bisect_left(grid, v) - 1, 0), len(grid) - 2)
    lo, hi = float(grid[i]), float(grid[i + 1])
    t = min(max((float(v) - lo) / (hi - lo), 0.0), 1.0)
    return (i, i + 1), (1.0 - t, t)


@dataclass(frozen=True)
class Library:
    """A response library of one sensor, read and checked (see the module docstring).

    Open one with :meth:`Library.open`; build one with
    :func:`fringekit.library.build_library` (``fringekit library build``).

    Attributes
    ----------
    folder : Path
        The library folder.
    manifest : dict
        ``manifest.json``: sensor, grid, lattice, mesh, versions, checksums.
    lattice : PolarLattice
        The polar lattice the fields are sampled on.
    load_N : ndarray (nF + 1,)
        Normal loads with the implied zero first (N).
    shear_ratio : ndarray (nS,)
        Tangential load over normal load.
    fields : dict
        Diameter (mm) -> dict of arrays (with the zero-load field prepended).
    stress_scale : float
        The factor the stored stresses are multiplied by when read (1 for a library as
        built; :meth:`scaled`).

    Examples
    --------
    A library is built by :func:`~fringekit.build_library` (there is an example there);
    opening checks it, and a folder that is no library is refused in one line:

    >>> import tempfile
    >>> from fringekit import Library, LibraryError
    >>> try:
    ...     Library.open(tempfile.mkdtemp())
    ... except LibraryError as exc:
    ...     print(str(exc).split(": ", 1)[1][:16])
    no manifest.json
    """

    folder: Path
    manifest: dict
    lattice: PolarLattice
    load_N: np.ndarray
    shear_ratio: np.ndarray
    fields: dict
    stress_scale: float = 1.0

    @classmethod
    def open(cls, folder: str | Path) -> Library:
        """Read and check a library folder (checksums, format, shapes); every defect is
        one :class:`~fringekit.errors.LibraryError` line."""
        return load_library(folder)

    def scaled(self, k: float) -> Library:
        """The library of the same sensor with a sheet ``k`` times stiffer: every load and
        every stress times ``k`` at the same deformed shape (docs/theory.md, "Modulus
        scaling"; exact up to the substrate's compliance, 5e-5 relative for a 15 % change
        on the built-in sensors). The fields are shared, not copied.

        Examples
        --------
        >>> import numpy as np
        >>> f = {"AB": np.ones((2, 2, 1, 1, 1, 2), np.float32),
        ...      "contact_radius_m": np.zeros((2, 2)), "centre_m": np.zeros((2, 2, 3))}
        >>> lib = Library(None, {}, None, np.array([0.0, 2.0]), np.array([0.0, 0.4]), {4.0: f})
        >>> stiff = lib.scaled(1.15)
        >>> stiff.max_load_N, round(float(stiff.state(4.0, 2.3, 0.0)[0].ravel()[0]), 6)
        (2.3, 1.15)
        """
        if not (np.isfinite(k) and k > 0):
            raise ValueError(f"modulus scale {k} is not allowed; give a factor > 0")
        return replace(self, load_N=self.load_N * k, stress_scale=self.stress_scale * k)

    @property
    def diameters_mm(self) -> list[float]:
        return sorted(self.fields)

    @property
    def max_load_N(self) -> float:
        return float(self.load_N[-1])

    @property
    def max_ratio(self) -> float:
        return float(self.shear_ratio[-1])

    def state(self, diameter_mm: float, fz: float, ratio: float):
        """The field of one load, in the library frame (tangential load along +x).

        Returns AB (R, F, S, 2), contact radius (m) and centre offset (3,) (m). Loads
        outside the grid are clamped: callers check :meth:`in_range` first.
        """
        f = self.fields[diameter_mm]
        iF, wF = _weights(self.load_N, fz)
        iS, wS = _weights(self.shear_ratio, ratio)
        AB = np.zeros(f["AB"].shape[2:], np.float32)
        a = 0.0
        c = np.zeros(3)
        for i, wi in zip(iF, wF, strict=True):
            for j, wj in zip(iS, wS, strict=True):
                w = wi * wj
                if w == 0.0:
                    continue
                AB += np.float32(w * self.stress_scale) * f["AB"][i, j]
                a += w * f["contact_radius_m"][i, j]
                c += w * f["centre_m"][i, j]
        return AB, a, c

    def in_range(self, fz: float, ratio: float, tol: float = 1e-6) -> bool:
        return 0.0 <= fz <= self.max_load_N * (1 + tol) and ratio <= self.max_ratio + tol

    def nearest_diameter(self, diameter_mm: float) -> float | None:
        for d in self.fields:
            if abs(d - diameter_mm) < 1e-6:
                return d
        return None

    def slabs(self, ind: LoadedIndenter, xy: np.ndarray):
        """Cartesian slab pairs of one indenter at pixel positions.

        Parameters
        ----------
        ind : LoadedIndenter
        xy : (P, 2) positions in the sensor frame (m)

        Returns
        -------
        ab : (P, S, 2) float32 — (sigma_xx - sigma_yy) dz and 2 sigma_xy dz (Pa m), zero
            beyond the lattice
        contact : (P,) bool — inside the indenter's contact circle
        """
        d = self.nearest_diameter(ind.diameter * 1e3)
        fz = max(ind.fz, 0.0)
        ft = float(np.hypot(ind.fx, ind.fy))
        ratio = ft / fz if fz > 0 else 0.0
        psi = float(np.arctan2(ind.fy, ind.fx)) if ft > 0 else 0.0
        AB, a, c = self.state(d, fz, min(ratio, self.max_ratio))
        ab = interpolate_turned(AB, self.lattice, xy[:, 0] - ind.x, xy[:, 1] - ind.y, psi)
        cp, sp = np.cos(psi), np.sin(psi)
        cx = ind.x + cp * c[0] - sp * c[1]
        cy = ind.y + sp * c[0] + cp * c[1]
        contact = np.hypot(xy[:, 0] - cx, xy[:, 1] - cy) < a
        return ab, contact


def check_sensor(lib, cfg: dict, where: str) -> None:
    """A library built for another sensor is refused, naming the first key that differs."""
    want, have = lib.manifest["sensor"], sensor_key(cfg)
    for table in want:
        a, b = want[table], have.get(table)
        if isinstance(a, dict):
            for k in a:
                if b is None or b.get(k) != a[k]:
                    raise LibraryError(
                        f"--library {lib.folder}: built for {table}.{k} = {a[k]!r}, but the "
                        f"image's sensor ({where}) has {b.get(k) if b else None!r}"
                    )
        elif a != b:
            raise LibraryError(
                f"--library {lib.folder}: built for {table} = {a!r}, but the "
                f"image's sensor ({where}) has {b!r}"
            )


def _bad(folder: Path, what: str) -> LibraryError:
    return LibraryError(f"--library {folder}: {what}")


def _rebuild(folder: Path, manifest: dict) -> str:
    """The command that builds a library of ``folder``'s sensor and grid anew."""
    command = f"fringekit library build {folder / 'config.toml'} --out {folder}-new"
    try:
        g = manifest["grid"]
        words = {
            "diameter-mm": g["diameters_mm"],
            "load-N": g["load_N"],
            "shear-ratio": g["shear_ratio"],
        }
        for option, values in words.items():
            command += f" --{option} " + " ".join(f"{float(v):g}" for v in values)
        return command + f" --slabs {int(manifest['lattice']['n_slabs'])}"
    except (KeyError, TypeError, ValueError):  # a damaged manifest: the sensor's defaults
        return command


def _check_manifest(folder: Path, manifest: dict) -> None:
    """The format, and the manifest's checksum of itself (an edited grid, diameter or
    lattice would give other loads and heads than the fields were solved for)."""
    fmt = manifest.get("format")
    if fmt in _OLD_FORMATS:
        raise _bad(
            folder,
            f"built by an earlier fringekit (format {fmt}: {_OLD_FORMATS[fmt]}); rebuild "
            f"it: {_rebuild(folder, manifest)}",
        )
    if fmt != FORMAT:
        raise _bad(folder, f"format {fmt!r} is not {FORMAT!r}")
    if manifest.get("manifest_sha256") != manifest_checksum(manifest):
        raise _bad(
            folder,
            "manifest.json does not match its own checksum (manifest_sha256): it was "
            "edited after the build (corrupt library; restore the file or rebuild it)",
        )


def load_library(folder) -> Library:
    """Read and check a library folder; every defect is one :class:`LibraryError` line."""
    folder = Path(folder)
    mf = folder / "manifest.json"
    if not mf.is_file():
        raise _bad(
            folder,
            "no manifest.json (not a library folder, or its build did not "
            "finish; `fringekit library build` resumes it)",
        )
    try:
        manifest = json.loads(mf.read_text())
    except ValueError as exc:
        raise _bad(folder, f"manifest.json is corrupt ({exc})") from None
    if not isinstance(manifest, dict):
        raise _bad(folder, "manifest.json is corrupt (not a JSON object)")
    _check_manifest(folder, manifest)
    try:
        lat = manifest["lattice"]
        lattice = PolarLattice(
            r=np.array(lat["r_mm"]) * 1e-3,
            phi=np.radians(np.array(lat["phi_deg"])),
            n_slabs=int(lat["n_slabs"]),
        )
        loads = np.array(manifest["grid"]["load_N"], float)
        ratios = np.array(manifest["grid"]["shear_ratio"], float)
        files = manifest["files"]
    except (ValueError, KeyError, TypeError) as exc:
        raise _bad(folder, f"manifest.json is corrupt ({exc})") from None
    fields = {}
    for name, info in files.items():
        path = folder / name
        if not path.is_file() or sha256(path) != info["sha256"]:
            raise _bad(
                folder,
                f"{name} is missing or does not match its checksum in "
                "manifest.json (corrupt library; rebuild it)",
            )
        with np.load(path) as z:
            f = {k: z[k] for k in FIELD_KEYS}
        expect = (len(loads), len(ratios), *lattice.shape, lattice.n_slabs, 2)
        if f["AB"].shape != expect:
            raise _bad(
                folder, f"{name} holds fields of shape {f['AB'].shape}, the manifest says {expect}"
            )
        zero = {k: np.zeros_like(v[:1]) for k, v in f.items()}
        fields[float(info["diameter_mm"])] = {k: np.concatenate([zero[k], v]) for k, v in f.items()}
    if not fields:
        raise _bad(folder, "manifest.json lists no field files")
    return Library(folder, manifest, lattice, np.concatenate([[0.0], loads]), ratios, fields)
