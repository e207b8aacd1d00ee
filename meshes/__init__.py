"""Stage 1 of the pipeline: bilayer sheet geometry and quadratic tetrahedral meshes."""

from .cache import UNREADABLE, build_mesh, cache_path, default_cache_dir
from .io import facet_grid, from_pyvista, load_npz, read_vtu, save_npz, to_pyvista, write_vtu
from .mesh import FACET_SETS, REGION_NAMES, REGION_SHEET, REGION_SUBSTRATE, FacetSet, Mesh
from .mirror import mirror, mirror_with_sources
from .quality import MeshQualityError, QualityReport, check_quality, quality_report
from .spec import IndenterSite, Layers, MeshSpec, Sizing

__all__ = [
    "FACET_SETS",
    "REGION_NAMES",
    "REGION_SHEET",
    "REGION_SUBSTRATE",
    "UNREADABLE",
    "FacetSet",
    "IndenterSite",
    "Layers",
    "Mesh",
    "MeshQualityError",
    "MeshSpec",
    "QualityReport",
    "Sizing",
    "build_mesh",
    "cache_path",
    "check_quality",
    "default_cache_dir",
    "facet_grid",
    "from_pyvista",
    "load_npz",
    "mirror",
    "mirror_with_sources",
    "quality_report",
    "read_vtu",
    "save_npz",
    "to_pyvista",
    "write_vtu",
]
