"""Meshes: exact geometry, conforming interface, facet sets, sizing, symmetry, cache, I/O."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SMALL_SIZING, small_spec

from fringekit.meshes import (
    REGION_SHEET,
    REGION_SUBSTRATE,
    IndenterSite,
    Layers,
    MeshSpec,
    Sizing,
    build_mesh,
    cache_path,
    from_pyvista,
    quality_report,
    read_vtu,
    to_pyvista,
    write_vtu,
)
from fringekit.meshes.quality import MeshQualityError, check_quality
from fringekit.meshes.topology import TET_EDGES, face_keys, unique_edges

SYMS = ("full", "half", "quarter")


def _area(spec):
    xmin, xmax, ymin, ymax, _, _ = spec.bounds()
    return (xmax - xmin) * (ymax - ymin)


@pytest.mark.parametrize("sym", SYMS)
def test_region_volumes_exact(small_meshes, sym):
    mesh = small_meshes[sym]
    spec = mesh.spec
    a = _area(spec)
    sheet = a * spec.layers.sheet_thickness
    sub = a * spec.layers.substrate_thickness
    assert mesh.region_volume(REGION_SHEET) == pytest.approx(sheet, rel=1e-9)
    assert mesh.region_volume(REGION_SUBSTRATE) == pytest.approx(sub, rel=1e-9)
    assert np.all(mesh.volumes > 0)


@pytest.mark.parametrize("sym", SYMS)
def test_midside_nodes_at_midpoints(small_meshes, sym):
    mesh = small_meshes[sym]
    p = mesh.points
    c = mesh.cells
    mids = 0.5 * (p[c[:, TET_EDGES[:, 0]]] + p[c[:, TET_EDGES[:, 1]]])
    np.testing.assert_allclose(p[c[:, 4:]], mids, rtol=0, atol=1e-15)
    # mid nodes are shared: one node per unique corner edge
    edges, _ = unique_edges(c[:, :4])
    assert len(np.unique(c[:, 4:])) == len(edges)


@pytest.mark.parametrize("sym", SYMS)
def test_flat_faces_are_exactly_planar(small_meshes, sym):
    mesh = small_meshes[sym]
    spec = mesh.spec
    xmin, xmax, ymin, ymax, zmin, zmax = spec.bounds()
    p = mesh.points
    expect = {"contact": [(2, zmax)], "bottom": [(2, zmin)], "interface": [(2, 0.0)]}
    if sym in ("half", "quarter"):
        expect["symmetry_y0"] = [(1, 0.0)]
    if sym == "quarter":
        expect["symmetry_x0"] = [(0, 0.0)]
    for name, planes in expect.items():
        nodes = mesh.facet_nodes(name)
        assert len(nodes) > 0, name
        ((axis, value),) = planes
        assert np.all(p[nodes, axis] == value), name
    side_nodes = mesh.facet_nodes("sides")
    on_side = np.zeros(side_nodes.shape[0], dtype=bool)
    side_planes = [(0, xmax), (1, ymax)]
    if sym != "quarter":
        side_planes.append((0, xmin))
    if sym == "full":
        side_planes.append((1, ymin))
    for axis, value in side_planes:
        on_side |= np.all(p[side_nodes, axis] == value, axis=1)
    assert on_side.all()


@pytest.mark.parametrize("sym", SYMS)
def test_facet_sets_cover_boundary_once(small_meshes, sym):
    mesh = small_meshes[sym]
    keys, _ = face_keys(mesh.cells[:, :4])
    _, inv, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    boundary = set(np.flatnonzero(counts[inv.ravel()] == 1).tolist())
    seen = []
    for name, fs in mesh.facets.items():
        if name == "interface":
            continue
        seen.extend((4 * fs.cells + fs.local).tolist())
    assert len(seen) == len(set(seen)), "a boundary face is in two sets"
    assert set(seen) == boundary


@pytest.mark.parametrize("sym", SYMS)
def test_interface_conforming_one_cell_each_side(small_meshes, sym):
    mesh = small_meshes[sym]
    fs = mesh.facets["interface"]
    assert np.all(mesh.regions[fs.cells] == REGION_SHEET)
    keys, _ = face_keys(mesh.cells[:, :4])
    iface = np.sort(mesh.facet_nodes("interface")[:, :3], axis=1)
    # every interface face appears in exactly two cells: one sheet, one substrate
    rows = {tuple(k): [] for k in iface.tolist()}
    for row, k in enumerate(keys.tolist()):
        t = tuple(k)
        if t in rows:
            rows[t].append(mesh.regions[row // 4])
    assert all(sorted(v) == [REGION_SHEET, REGION_SUBSTRATE] for v in rows.values())
    # the interface covers the full cross-section
    p = mesh.points
    tri = p[iface]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.sum() == pytest.approx(_area(mesh.spec), rel=1e-12)
    # facet normals point out of the sheet (down) for the interface, up for contact
    tri = p[mesh.facet_nodes("interface")[:, :3]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(n[:, 2] < 0)
    top = p[mesh.facet_nodes("contact")[:, :3]]
    assert np.all(np.cross(top[:, 1] - top[:, 0], top[:, 2] - top[:, 0])[:, 2] > 0)


@pytest.mark.parametrize("sym", SYMS)
def test_symmetry_mesh_lies_in_its_part(small_meshes, sym):
    p = small_meshes[sym].points
    if sym in ("half", "quarter"):
        assert p[:, 1].min() == 0.0
    if sym == "quarter":
        assert p[:, 0].min() == 0.0
    if sym == "full":
        assert p[:, 0].min() < 0 and p[:, 1].min() < 0


def _mean_edge_in_zone(mesh, ind, radius):
    """Mean lateral (z = const) edge length in the sheet within radius of an indenter,
    plus all edges: length, distance from the axis, midpoint. Prism-split tets also have
    vertical edges (checked by the z levels) and quadrilateral diagonals (longer)."""
    edges, _ = unique_edges(mesh.cells[:, :4])
    p = mesh.points
    mid = 0.5 * (p[edges[:, 0]] + p[edges[:, 1]])
    vec = p[edges[:, 0]] - p[edges[:, 1]]
    length = np.linalg.norm(vec, axis=1)
    r = np.hypot(mid[:, 0] - ind.x, mid[:, 1] - ind.y)
    lateral = vec[:, 2] == 0
    return length[(r < radius) & (mid[:, 2] > 0) & lateral].mean(), length, r, mid


@pytest.mark.parametrize("sym", SYMS)
def test_refined_zone_edge_length(small_meshes, sym):
    mesh = small_meshes[sym]
    siz = mesh.spec.sizing
    ind = mesh.spec.indenters[0]
    mean, length, r, mid = _mean_edge_in_zone(mesh, ind, siz.refine_radius)
    assert mean <= 1.2 * siz.h_contact
    far = length[(r > siz.refine_radius + 2e-3) & (mid[:, 2] < 0)]
    assert far.mean() > 1.5 * mean


def test_four_indenter_plate(cache_dir):
    s = 4e-3
    sites = tuple(IndenterSite(x, y, 1e-3) for x in (-s, s) for y in (-s, s))
    spec = MeshSpec(
        layers=Layers(3e-3, 3e-3, 16e-3, 16e-3),
        indenters=sites,
        sizing=Sizing(
            h_contact=0.6e-3, refine_radius=1.2e-3, h_far=3e-3, h_sheet=1.5e-3, growth=0.5
        ),
        symmetry="quarter",
    )
    mesh = build_mesh(spec, cache_dir=cache_dir)
    assert mesh.region_volume(REGION_SHEET) == pytest.approx(8e-3 * 8e-3 * 3e-3, rel=1e-9)
    mean, *_ = _mean_edge_in_zone(mesh, sites[3], 1.2e-3)
    assert mean <= 1.2 * 0.6e-3
    assert spec.kept_indenters() == (sites[3],)


def test_single_layer_has_no_interface(cache_dir):
    spec = small_spec("quarter", layers=Layers(3e-3, 0.0, 10e-3, 10e-3))
    mesh = build_mesh(spec, cache_dir=cache_dir)
    assert len(mesh.facets["interface"]) == 0
    assert np.all(mesh.regions == REGION_SHEET)
    assert np.all(mesh.points[mesh.facet_nodes("bottom"), 2] == 0.0)
    assert mesh.region_volume(REGION_SHEET) == pytest.approx(5e-3 * 5e-3 * 3e-3, rel=1e-9)


def test_quality_report(small_meshes):
    mesh = small_meshes["quarter"]
    rep = quality_report(mesh.points, mesh.cells, mesh.regions)
    assert rep.n_cells == mesh.n_cells
    assert sum(rep.cells_per_region.values()) == mesh.n_cells
    assert 5.0 < rep.min_dihedral_deg < 70.6
    assert 0.05 < rep.min_radius_ratio <= rep.mean_radius_ratio <= 1.0
    assert "DOF" in str(rep)


def test_quality_measures_on_regular_tet():
    p = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    from fringekit.meshes.quality import dihedral_angles, radius_ratios

    c = np.array([[0, 1, 2, 3]])
    if np.linalg.det(p[1:] - p[0]) < 0:
        c = c[:, [0, 2, 1, 3]]
    np.testing.assert_allclose(dihedral_angles(p, c), np.degrees(np.arccos(1 / 3)), rtol=1e-12)
    np.testing.assert_allclose(radius_ratios(p, c), 1.0, rtol=1e-12)


def test_inverted_and_degenerate_elements_rejected():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 1e-9]], float)
    with pytest.raises(MeshQualityError, match="inverted"):
        check_quality(p, np.array([[0, 2, 1, 3]]))
    with pytest.raises(MeshQualityError, match="degenerate"):
        check_quality(p, np.array([[0, 1, 2, 4]]))


def test_cache_hit_is_identical(small_meshes, cache_dir):
    spec = small_meshes["quarter"].spec
    assert cache_path(spec, cache_dir).exists()
    again = build_mesh(spec, cache_dir=cache_dir)
    assert again.same_as(small_meshes["quarter"])
    other = small_spec("quarter", sizing=Sizing(0.5e-3, 1.5e-3, 3e-3, 1.5e-3, 0.5))
    assert cache_path(other, cache_dir) != cache_path(spec, cache_dir)


def test_vtu_round_trip_exact(small_meshes, tmp_path):
    mesh = small_meshes["half"]
    path = write_vtu(mesh, tmp_path / "m.vtu")
    back = read_vtu(path)
    assert back.same_as(mesh)
    assert from_pyvista(to_pyvista(mesh)).same_as(mesh)
    grid = to_pyvista(mesh)
    assert grid.n_cells == mesh.n_cells and "region" in grid.cell_data


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(layers=dict(sheet_thickness=0.0)), "sheet_thickness"),
        (dict(layers=dict(width=-1.0)), "width"),
        (dict(layers=dict(substrate_thickness=-1e-3)), "substrate_thickness"),
        (dict(sizing=dict(h_contact=0.0)), "h_contact"),
        (dict(sizing=dict(growth=float("nan"))), "growth"),
        (dict(sizing=dict(h_contact=4e-3, h_sheet=5e-3, h_far=6e-3)), "sheet thickness"),
        (dict(indenters=[IndenterSite(19e-3, 0.0, 1.75e-3)]), "outside the sheet"),
        (
            dict(indenters=[IndenterSite(0, 0, 1e-3), IndenterSite(1.5e-3, 0, 1e-3)]),
            "overlap",
        ),
        (dict(indenters=[IndenterSite(0, 3e-3, 1e-3)], symmetry="half"), "mirror image"),
        (dict(indenters=[IndenterSite(3e-3, 0, 1e-3)], symmetry="quarter"), "plane x = 0"),
        (dict(symmetry="eighth"), "symmetry"),
        (dict(indenters=[]), "indenters"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, match):
    layers = kwargs.pop("layers", {})
    sizing = kwargs.pop("sizing", {})
    with pytest.raises(ValueError, match=match):
        base_sizing = dict(
            h_contact=0.3e-3, refine_radius=2e-3, h_far=4e-3, h_sheet=1e-3, growth=0.4
        )
        MeshSpec(layers=Layers(**layers), sizing=Sizing(**{**base_sizing, **sizing}), **kwargs)


def test_symmetric_sets_accepted():
    sites = [IndenterSite(x, y, 1e-3) for x in (-4e-3, 4e-3) for y in (-4e-3, 4e-3)]
    assert MeshSpec(indenters=sites, symmetry="quarter").kept_indenters()[0].x == 4e-3
    assert MeshSpec(indenters=[IndenterSite(3e-3, 0, 1e-3)], symmetry="half")
    assert SMALL_SIZING.h_contact < SMALL_SIZING.h_sheet


@pytest.mark.slow
def test_meshing_leaves_the_working_directory_clean(tmp_path, monkeypatch):
    """fTetWild writes a debug STL into the cwd; the tetwild mesher must keep it out of there.

    The test block of the other tests: this test used an 8 x 8 mm block on 2 mm of
    polycarbonate, where fTetWild stalled (5-8 minutes instead of 2-16 s) on 2 of 44
    repeats; see meshes.tetwild.FTETWILD_MAX_PASSES."""
    import pytetwild

    from fringekit.meshes.tetwild import FTETWILD_MAX_PASSES

    seen = {}
    real = pytetwild.tetrahedralize

    def spy(*args, **kw):
        seen.update(kw)
        return real(*args, **kw)

    monkeypatch.setattr(pytetwild, "tetrahedralize", spy)
    monkeypatch.chdir(tmp_path)
    build_mesh(small_spec("quarter", mesher="tetwild"), use_cache=False)
    assert list(tmp_path.iterdir()) == []
    # and the optimisation passes are capped (fTetWild's 80 let a stuck mesh grow 100x)
    assert seen["num_opt_iter"] == FTETWILD_MAX_PASSES <= 20


_HASH_SCRIPT = """
import hashlib, sys
from fringekit.meshes import MeshSpec, build_mesh, IndenterSite, Layers
specs = [MeshSpec(symmetry="quarter"),
         MeshSpec(layers=Layers(2e-3, 15e-3, 30e-3, 30e-3),
                  indenters=(IndenterSite(-4e-3, 0.0), IndenterSite(4e-3, 2e-3)))]
h = hashlib.sha256()
for spec in specs:
    m = build_mesh(spec, cache_dir=sys.argv[1])
    for a in (m.points, m.cells, m.regions):
        h.update(a.tobytes())
    for name in sorted(m.facets):
        h.update(name.encode() + m.facets[name].cells.tobytes() + m.facets[name].local.tobytes())
print(h.hexdigest())
"""


@pytest.mark.slow
def test_same_spec_gives_the_same_mesh_in_fresh_processes(tmp_path):
    """The layered mesher is deterministic: two processes with empty caches make the
    reference quarter model and a two-indenter full model node for node identical."""
    import subprocess
    import sys

    digests = [
        subprocess.run(
            [sys.executable, "-c", _HASH_SCRIPT, str(tmp_path / f"cache{k}")],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        for k in range(2)
    ]
    assert len(digests[0]) == 64 and digests[0] == digests[1]


@pytest.mark.parametrize("sym", SYMS)
def test_plane_triangulation_quality_and_exact_boundary(sym):
    from fringekit.meshes.plane import plane_size, triangulate_plane

    spec = small_spec(sym)
    p, tri = triangulate_plane(spec)
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    area = 0.5 * (
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    )
    assert np.all(area > 0)  # counter-clockwise, none degenerate
    xmin, xmax, ymin, ymax, _, _ = spec.bounds()
    assert area.sum() == pytest.approx((xmax - xmin) * (ymax - ymin), rel=1e-12)
    sq = [np.sum((u - v) ** 2, axis=1) for u, v in ((b, c), (c, a), (a, b))]
    quality = 4 * np.sqrt(3) * area / sum(sq)  # 1 for an equilateral triangle
    assert quality.min() > 0.6 and quality.mean() > 0.9
    # edge lengths follow the target size within 25 % on average
    edge = np.sqrt(np.concatenate(sq))
    mids = np.concatenate([0.5 * (u + v) for u, v in ((b, c), (c, a), (a, b))])
    ratio = edge / plane_size(spec, mids)
    assert 0.85 < np.median(ratio) < 1.25


def test_extruded_prisms_are_conforming():
    """Two triangles sharing an edge, swept through two layers: every internal face is
    shared by exactly two tets (the Dompierre diagonal rule), the volume is exact."""
    from fringekit.meshes.layered import extrude
    from fringekit.meshes.topology import orient_positive, signed_volumes

    p2 = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    for tris in (np.array([[0, 1, 2], [1, 3, 2]]), np.array([[2, 0, 1], [3, 2, 1]])):
        pts, tets = extrude(p2, tris, np.array([0.0, 0.5, 2.0]))
        tets = orient_positive(pts, tets)
        vol = signed_volumes(pts, tets)
        assert np.all(vol > 0) and vol.sum() == pytest.approx(2.0, rel=1e-14)
        keys, _ = face_keys(tets)
        _, counts = np.unique(keys, axis=0, return_counts=True)
        # faces: 2 layers x 2 prisms x 3 tets x 4 = 48; boundary: 2 + 2 top/bottom
        # triangles + 4 sides x 2 layers x 2 = 20; the other 28 pair up into 14
        assert np.sum(counts == 1) == 20 and np.sum(counts == 2) == 14 and counts.max() == 2


def test_z_levels_cover_the_layers_exactly():
    from fringekit.meshes.layered import SUBSTRATE_ASPECT, SUBSTRATE_CAP, z_levels

    spec = MeshSpec(symmetry="quarter")
    z = z_levels(spec)
    assert z[0] == -spec.layers.substrate_thickness and z[-1] == spec.layers.sheet_thickness
    assert 0.0 in z and np.all(np.diff(z) > 0)
    dz_sheet = np.diff(z[z >= 0])
    thickest = max(spec.sizing.h_contact, spec.sizing.h_layer)
    assert np.allclose(dz_sheet, dz_sheet[0]) and dz_sheet[0] <= thickest * (1 + 1e-12)
    siz = spec.sizing
    cap = min(SUBSTRATE_CAP * siz.h_sheet, siz.h_far, SUBSTRATE_ASPECT * siz.h_contact)
    assert np.diff(z).max() <= 1.5 * cap  # a dropped last layer stretches the others


@pytest.mark.parametrize("h_contact", [0.3e-3, 0.2e-3, 0.15e-3])
def test_a_fine_contact_mesh_on_a_thick_substrate_keeps_its_tets_sound(h_contact):
    """The contact zone's small triangles are swept through every substrate layer: on the
    reference sensor's 15 mm substrate, layers of up to 6.3 mm gave 0.99 deg tets at
    h_contact 0.2 mm, which the quality check refused. The layers are now capped at
    SUBSTRATE_ASPECT h_contact, which keeps the smallest dihedral above 1.5 deg."""
    from fringekit.meshes.layered import layered_tets
    from fringekit.meshes.quality import dihedral_angles

    layers = Layers(sheet_thickness=3e-3, substrate_thickness=15e-3, width=20e-3, length=20e-3)
    sizing = Sizing(h_contact=h_contact, refine_radius=2e-3, h_sheet=2e-3, h_far=8e-3)
    spec = MeshSpec(layers, (IndenterSite(radius=1.75e-3),), sizing, symmetry="quarter")
    pts, tets = layered_tets(spec)
    assert dihedral_angles(pts, tets).min() > 1.5


@pytest.mark.parametrize(
    "h_contact, h_layer, n_sheet",
    [(0.6e-3, 0.0, 5), (0.3e-3, 0.0, 10), (0.3e-3, 0.6e-3, 5), (1.0e-3, 0.6e-3, 3)],
)
def test_sheet_layers_follow_the_coarser_of_h_contact_and_h_layer(h_contact, h_layer, n_sheet):
    """The lateral size may be finer than the sheet's layers (3 mm sheet): the layers are
    max(h_contact, h_layer) thick or less, in equal steps; h_layer 0 follows h_contact."""
    from fringekit.config.memory import mesh_tets
    from fringekit.meshes.layered import z_levels

    spec = MeshSpec(sizing=Sizing(h_contact=h_contact, h_layer=h_layer), symmetry="quarter")
    dz = np.diff(z_levels(spec)[z_levels(spec) >= 0])
    assert len(dz) == n_sheet and np.allclose(dz, 3e-3 / n_sheet, rtol=1e-12, atol=0)
    assert mesh_tets(spec)[1] == n_sheet  # the memory check counts the same layers
