"""The memory a config's mesh and ray samples will need, checked before meshing.

Both estimates count the largest arrays only (:mod:`fringekit._memory`); a config whose
estimate exceeds the memory free is refused naming its keys, instead of failing with
``MemoryError`` after minutes of meshing or solving.
"""

from __future__ import annotations

import math

from fringekit._memory import check_memory
from fringekit.errors import ConfigError

__all__ = ["BYTES_PER_TET", "check_mesh_memory", "check_ray_memory", "mesh_tets", "ray_bytes"]

#: Memory per tetrahedron :func:`mesh_tets` counts (bytes), measured: the small case at
#: h_contact_mm = h_layer_mm = 0.08, full model, meshed 458,832 quadratic tets (the
#: count: 290,800) and wrote them with 290 MB above the interpreter's 230 MB: about 1 kB
#: per counted tet.
BYTES_PER_TET = 1000.0
#: The part of the sensor a model of each symmetry holds.
PART = {"full": 1.0, "half": 0.5, "quarter": 0.25}


def mesh_tets(spec) -> tuple[float, int]:
    """About how many tets the mesh of ``spec`` (a :class:`~fringekit.meshes.MeshSpec`)
    has under its indenters, and the sheet's layers: the sheet is split into
    ceil(thickness / max(h_contact, h_layer)) layers (the layered mesher's rule) and each
    refined disc (refine_radius about each indenter, at most the sheet) into triangles of
    side h_contact (area sqrt(3)/4 h^2), each extruded prism 3 tets; times the modelled
    part.
    The graded zone and the substrate add about half again (a lower bound).

    Examples
    --------
    >>> from fringekit.config.inputs import mesh_spec
    >>> from fringekit.config.memory import mesh_tets
    >>> from fringekit.config.model import as_config
    >>> fine = {"mesh.h_contact_mm": 0.08, "mesh.h_layer_mm": 0.08, "mesh.symmetry": "full"}
    >>> tets, layers = mesh_tets(mesh_spec(as_config("small").replace(fine).data))
    >>> round(tets, -3), layers
    (291000.0, 38)
    """
    lay, siz = spec.layers, spec.sizing
    layers = math.ceil(lay.sheet_thickness / max(siz.h_contact, siz.h_layer) - 1e-9)
    discs = len(spec.indenters) * math.pi * siz.refine_radius**2
    area = min(discs, lay.width * lay.length)
    triangles = area / (math.sqrt(3) / 4 * siz.h_contact**2)
    return 3.0 * layers * triangles * PART.get(spec.symmetry, 1.0), layers


def check_mesh_memory(cfg: dict, spec) -> None:
    """Refuse a ``mesh.h_contact_mm`` whose mesh needs more memory than is free
    (:func:`mesh_tets` x BYTES_PER_TET).

    Examples
    --------
    >>> from fringekit.config.inputs import mesh_spec
    >>> from fringekit.config.memory import check_mesh_memory
    >>> from fringekit.config.model import as_config
    >>> cfg = as_config("small").data
    >>> check_mesh_memory(cfg, mesh_spec(cfg))  # a few hundred tets: nothing to say
    """
    tets, layers = mesh_tets(spec)
    h = cfg["mesh"]["h_contact_mm"]
    check_memory(
        tets * BYTES_PER_TET,
        f"about {tets:.2g} tets under the indenters (the {cfg['sheet']['thickness_mm']:g} mm "
        f"sheet in {layers} layers)",
        f"mesh.h_contact_mm = {h:g}",
        hint="give a larger mesh.h_contact_mm",
        error=ConfigError,
    )


def ray_bytes(cfg: dict, symmetry: str) -> float:
    """Memory (bytes) of the ray samples of one load state: pixels^2 rays (times the
    modelled part: the rays of a symmetric model are folded onto it) x the samples per
    ray of the sheet (and of the substrate when it is included) x 5 float64 arrays alive
    at once (the slab pairs a, b, and the retardation, angle and thickness made of them).

    Examples
    --------
    >>> from fringekit.config.memory import ray_bytes
    >>> from fringekit.config.model import as_config
    >>> ray_bytes(as_config("small").data, "quarter")  # 64 x 64 px, 24 samples: 1 MB
    983040.0
    """
    o = cfg["optics"]
    samples = o["samples_per_ray"] + (o["substrate_samples_per_ray"] * o["include_substrate"])
    return float(o["pixels"]) ** 2 * PART.get(symmetry, 1.0) * samples * 5 * 8


def check_ray_memory(cfg: dict, symmetry: str) -> None:
    """Refuse ``optics.pixels`` and ``optics.samples_per_ray`` whose ray samples
    (:func:`ray_bytes`) need more memory than is free.

    Examples
    --------
    >>> from fringekit.config.memory import check_ray_memory
    >>> from fringekit.config.model import as_config
    >>> check_ray_memory(as_config("small").data, "quarter")  # 1 MB: nothing to say
    """
    o = cfg["optics"]
    keys = f"optics.pixels = {o['pixels']} with optics.samples_per_ray = {o['samples_per_ray']}"
    if o["include_substrate"]:
        keys += f" (substrate {o['substrate_samples_per_ray']})"
    check_memory(
        ray_bytes(cfg, symmetry),
        f"the ray samples of one load state ({o['pixels']} x {o['pixels']} px, {symmetry} model)",
        keys,
        hint="give fewer pixels or samples per ray",
        error=ConfigError,
    )
