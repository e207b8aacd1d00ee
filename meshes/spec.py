"""Inputs of the mesher: sheet geometry, indenter sites, sizing and symmetry.

All lengths are in metres (SI, ``docs/theory.md``, "Conventions"). The geometry
frame: the sheet spans ``x in [-width/2, width/2]``, ``y in [-length/2, length/2]``;
the sheet/substrate interface is the plane ``z = 0``, the contact face (top) is
``z = sheet_thickness`` and the bottom of the substrate is
``z = -substrate_thickness``. A half model keeps ``y >= 0`` (mirror plane
``y = 0``, compatible with shear along x); a quarter model keeps ``x >= 0`` and
``y >= 0``.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from typing import Literal

__all__ = ["Layers", "IndenterSite", "Sizing", "MeshSpec", "SYMMETRIES", "MESHERS"]

SYMMETRIES = ("full", "half", "quarter")
Symmetry = Literal["full", "half", "quarter"]
#: ``"layered"``: deterministic extruded plane triangulation; ``"tetwild"``: fTetWild.
MESHERS = ("layered", "tetwild")
Mesher = Literal["layered", "tetwild"]


def _positive(name: str, value: float, *, allow_zero: bool = False) -> None:
    ok = math.isfinite(value) and (value >= 0 if allow_zero else value > 0)
    if not ok:
        allowed = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} = {value!r} is not allowed; it must be finite and {allowed} (m)")


@dataclass(frozen=True)
class Layers:
    """The bonded layer stack.

    Parameters
    ----------
    sheet_thickness : float
        Photoelastic sheet thickness (m). Default 3 mm (seed paper, "Sensing element").
    substrate_thickness : float
        Polycarbonate substrate thickness (m); 0 gives a single sheet whose bottom
        face is the fixed base. Default 15 mm (seed paper).
    width, length : float
        Lateral size along x and y of the full sheet (m). Default 40 mm x 40 mm
        (assumed: large enough that the free sides barely affect a 3.5 mm indenter).

    Raises
    ------
    ValueError
        A thickness or size that is not finite and positive (the substrate may be 0).

    Examples
    --------
    >>> from fringekit.meshes import Layers
    >>> lay = Layers(sheet_thickness=3e-3, substrate_thickness=15e-3)
    >>> lay.z_top, lay.z_bottom
    (0.003, -0.015)
    >>> Layers(substrate_thickness=0.0).z_bottom  # a single sheet on a rigid base
    0.0
    """

    sheet_thickness: float = 3e-3
    substrate_thickness: float = 15e-3
    width: float = 40e-3
    length: float = 40e-3

    def __post_init__(self) -> None:
        _positive("layers.sheet_thickness", self.sheet_thickness)
        _positive("layers.substrate_thickness", self.substrate_thickness, allow_zero=True)
        _positive("layers.width", self.width)
        _positive("layers.length", self.length)

    @property
    def z_top(self) -> float:
        """z of the contact face (m)."""
        return self.sheet_thickness

    @property
    def z_bottom(self) -> float:
        """z of the fixed bottom face (m)."""
        return -self.substrate_thickness if self.substrate_thickness > 0 else 0.0


@dataclass(frozen=True)
class IndenterSite:
    """Where an indenter touches the sheet: centre (x, y) and sphere radius (m).

    Parameters
    ----------
    x, y : float
        Centre of the contact on the undeformed contact face (m), in the frame of the
        FULL sheet (origin at its centre).
    radius : float
        Sphere radius (m). Default: the reference 3.5 mm diameter head (seed paper,
        Fig. 3).

    Raises
    ------
    ValueError
        A non-finite centre or a radius that is not > 0.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite
    >>> IndenterSite(x=5e-3, radius=2e-3)
    IndenterSite(x=0.005, y=0.0, radius=0.002)
    """

    x: float = 0.0
    y: float = 0.0
    radius: float = 1.75e-3

    def __post_init__(self) -> None:
        for name in ("x", "y"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"indenter.{name} = {v!r} is not allowed; it must be finite (m)")
        _positive("indenter.radius", self.radius)


@dataclass(frozen=True)
class Sizing:
    """Target tetrahedron edge lengths (m).

    Parameters
    ----------
    h_contact : float
        Edge length in the refined zone under each indenter: a cylinder of radius
        ``refine_radius`` about the indenter axis through the whole sheet. Default
        0.3 mm (on ``h_layer`` 0.6 mm layers): on the reference case at 8 N the fringe
        order 1.5-6 mm from the axis is within 0.015 fringe, and the contact radius within
        1.5 %, of a 236k-DOF mesh; 0.6 mm was 0.16 fringe and 5 % off
        (``docs/validation.md``, faceted rings).
    refine_radius : float
        Radius of the refined zone (m). Default 2 mm, about 1.6 contact radii of the
        reference 8 N case (contact radius ~0.7 R = 1.2 mm).
    h_far : float
        Largest edge length anywhere (m). Default 8 mm.
    h_sheet : float
        Largest edge length inside the sheet (m), so that stresses are resolved
        through its thickness everywhere the camera looks. Default 2 mm (quadratic
        elements: two through the 3 mm sheet).
    growth : float
        Grading rate: the target size grows by ``growth`` per unit distance from the
        refined zone (dimensionless, > 0).
    h_layer : float
        Thinnest element layer of the sheet (m; layered mesher only): the sheet is cut
        into equal layers ``max(h_contact, h_layer)`` thick or less; 0 makes the layers
        follow ``h_contact``. Default 0.6 mm: on the reference case at h_contact 0.3 mm,
        ten layers instead of five moved the fringe order 1.5-6 mm out by at most 0.024
        fringe and the contact radius by 0.4 %, for three times the solve time. Lower it
        with ``h_contact`` for contacts much smaller than 1 mm in radius.

    Raises
    ------
    ValueError
        A size that is not > 0, or not ``h_contact <= h_sheet <= h_far``.

    Examples
    --------
    A coarse sizing for quick checks:

    >>> from fringekit.meshes import Sizing
    >>> Sizing(h_contact=1e-3, h_sheet=2e-3).h_far
    0.008
    """

    h_contact: float = 0.3e-3
    refine_radius: float = 2e-3
    h_far: float = 8e-3
    h_sheet: float = 2e-3
    growth: float = 0.4
    h_layer: float = 0.6e-3

    def __post_init__(self) -> None:
        for name in ("h_contact", "refine_radius", "h_far", "h_sheet", "growth"):
            _positive(f"sizing.{name}", getattr(self, name))
        _positive("sizing.h_layer", self.h_layer, allow_zero=True)
        if self.h_contact > self.h_sheet:
            raise ValueError(
                f"sizing.h_contact = {self.h_contact!r} m is larger than sizing.h_sheet = "
                f"{self.h_sheet!r} m; the refined size must not exceed the sheet size"
            )
        if self.h_sheet > self.h_far:
            raise ValueError(
                f"sizing.h_sheet = {self.h_sheet!r} m is larger than sizing.h_far = "
                f"{self.h_far!r} m; allowed: h_contact <= h_sheet <= h_far"
            )


@dataclass(frozen=True)
class MeshSpec:
    """Everything the mesh depends on; its hash is the cache key.

    Parameters
    ----------
    layers : Layers
        The bonded sheet/substrate stack.
    indenters : tuple of IndenterSite
        Indenter sites on the contact face of the FULL sheet (before symmetry cuts).
    sizing : Sizing
        Target edge lengths.
    symmetry : {"full", "half", "quarter"}
        ``"half"`` keeps y >= 0 (mirror plane y = 0); ``"quarter"`` keeps x >= 0 and
        y >= 0. Only allowed when the indenter set is mirror-symmetric accordingly.
    mesher : {"layered", "tetwild"}
        ``"layered"`` (default) extrudes a graded plane triangulation through the
        layers and gives the same mesh on every run; ``"tetwild"`` runs fTetWild, whose
        mesh changes from run to run.

    Raises
    ------
    ValueError
        An unknown symmetry or mesher, no indenter, indenters outside the sheet or
        overlapping, a refined size thicker than the sheet, or a symmetry the indenter
        set does not have.

    Examples
    --------
    The default is the reference sensor (3 mm sheet on 15 mm polycarbonate, 40 x 40 mm,
    one 3.5 mm head at the centre); a small single-layer quarter model meshes in
    milliseconds:

    >>> from fringekit.meshes import MeshSpec
    >>> MeshSpec().layers.sheet_thickness
    0.003
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> spec.bounds()  # (xmin, xmax, ymin, ymax, zmin, zmax) of the quarter, m
    (0.0, 0.005, 0.0, 0.005, 0.0, 0.002)
    >>> MeshSpec.from_dict(spec.to_dict()) == spec
    True
    """

    layers: Layers = field(default_factory=Layers)
    indenters: tuple[IndenterSite, ...] = (IndenterSite(),)
    sizing: Sizing = field(default_factory=Sizing)
    symmetry: Symmetry = "full"
    mesher: Mesher = "layered"

    def __post_init__(self) -> None:
        object.__setattr__(self, "indenters", tuple(self.indenters))
        if self.symmetry not in SYMMETRIES:
            raise ValueError(
                f"symmetry = {self.symmetry!r} is not allowed; use one of {SYMMETRIES}"
            )
        if self.mesher not in MESHERS:
            raise ValueError(f"mesher = {self.mesher!r} is not allowed; use one of {MESHERS}")
        if len(self.indenters) == 0:
            raise ValueError("indenters = () is not allowed; give at least one IndenterSite")
        lay, siz = self.layers, self.sizing
        if siz.h_contact > lay.sheet_thickness:
            raise ValueError(
                f"sizing.h_contact = {siz.h_contact!r} m is larger than the sheet thickness "
                f"{lay.sheet_thickness!r} m; allowed: h_contact <= sheet_thickness"
            )
        for k, ind in enumerate(self.indenters):
            if abs(ind.x) + ind.radius > lay.width / 2 or abs(ind.y) + ind.radius > lay.length / 2:
                raise ValueError(
                    f"indenters[{k}] at (x, y) = ({ind.x!r}, {ind.y!r}) m with radius "
                    f"{ind.radius!r} m is outside the sheet; allowed: |x| + radius <= "
                    f"{lay.width / 2!r} m and |y| + radius <= {lay.length / 2!r} m"
                )
        for i in range(len(self.indenters)):
            for j in range(i + 1, len(self.indenters)):
                a, b = self.indenters[i], self.indenters[j]
                d = math.hypot(a.x - b.x, a.y - b.y)
                if d < a.radius + b.radius:
                    raise ValueError(
                        f"indenters[{i}] and indenters[{j}] overlap: centre distance {d!r} m < "
                        f"sum of radii {a.radius + b.radius!r} m"
                    )
        if self.symmetry in ("half", "quarter"):
            self._check_mirror(axis=1)
        if self.symmetry == "quarter":
            self._check_mirror(axis=0)

    def _check_mirror(self, axis: int) -> None:
        """Raise unless the indenter set maps onto itself under x_axis -> -x_axis."""
        plane = "y = 0" if axis == 1 else "x = 0"
        tol = 1e-9
        sites = [(i.x, i.y, i.radius) for i in self.indenters]
        for k, (x, y, r) in enumerate(sites):
            mx, my = (x, -y) if axis == 1 else (-x, y)
            if not any(
                abs(mx - x2) < tol and abs(my - y2) < tol and abs(r - r2) < tol
                for x2, y2, r2 in sites
            ):
                raise ValueError(
                    f"symmetry = {self.symmetry!r} is not allowed: indenters[{k}] at "
                    f"({x!r}, {y!r}) m has no mirror image about the plane {plane}; "
                    f"use symmetry = 'full' or a mirror-symmetric indenter set"
                )

    def kept_indenters(self) -> tuple[IndenterSite, ...]:
        """Indenters whose centre lies in the modelled part (on a symmetry plane counts)."""
        keep = []
        for ind in self.indenters:
            if self.symmetry in ("half", "quarter") and ind.y < 0:
                continue
            if self.symmetry == "quarter" and ind.x < 0:
                continue
            keep.append(ind)
        return tuple(keep)

    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """(xmin, xmax, ymin, ymax, zmin, zmax) of the modelled domain (m)."""
        w, l = self.layers.width / 2, self.layers.length / 2
        xmin = 0.0 if self.symmetry == "quarter" else -w
        ymin = 0.0 if self.symmetry in ("half", "quarter") else -l
        return (xmin, w, ymin, l, self.layers.z_bottom, self.layers.z_top)

    def to_dict(self) -> dict:
        """Plain-JSON form (SI units), the inverse of :meth:`from_dict`."""
        d = asdict(self)
        d["indenters"] = [asdict(i) for i in self.indenters]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> MeshSpec:
        """Rebuild a spec from :meth:`to_dict` output."""
        return cls(
            layers=Layers(**d["layers"]),
            indenters=tuple(IndenterSite(**i) for i in d["indenters"]),
            sizing=Sizing(**d["sizing"]),
            symmetry=d["symmetry"],
            mesher=d.get("mesher", "tetwild"),  # files written before the layered mesher
        )

    def key(self, salt: str = "") -> str:
        """SHA-256 hex digest of the canonical JSON of the spec (plus ``salt``)."""
        text = json.dumps(self.to_dict(), sort_keys=True, allow_nan=False) + salt
        return hashlib.sha256(text.encode()).hexdigest()
