"""A synthetic 3D `FingertipMesh`: the four tissues as horizontal slabs of a half block with the
fingertip's tags (pulp below, nail centre strip on top, symmetry and proximal-cut planes): the
3D problem's wiring without the fingertip geometry."""

from __future__ import annotations

import numpy as np
from dolfinx import mesh
from mpi4py import MPI

from ...geometry.mesh import CELL_TAGS, FACET_TAGS_3D, FingertipMesh

#: Slab tops (mm) of the layered block from its bottom y = −3: skin 0.5 mm, subcutaneous 3 mm,
#: bone 0.5 mm, nail 0.5 mm (round numbers of the section's proportions, not its geometry).
LAYERS = (("skin", -2.5), ("subcutaneous", 0.5), ("bone", 1.0), ("nail", 1.5))


def layered_block(comm=MPI.COMM_SELF, *, half_width: float = 3.0, length: float = 6.0,
                  cells_per_mm: float = 2.0, centre_half_width: float = 1.0) -> FingertipMesh:
    """The half block [0, half_width] × [−3, 1.5] × [0, length] (mm) of tetrahedra, its cells
    tagged as the slabs of `LAYERS` and its facets as the fingertip's: pulp_surface (y = −3,
    where indenters act), nail_centre (the top's strip x < centre_half_width), symmetry
    (x = 0), proximal_cut (z = 0), outer_surface (the rest). 2 cells per mm put every slab
    boundary on a cell layer."""
    y0, y1 = -3.0, LAYERS[-1][1]
    n = [max(1, round(d * cells_per_mm)) for d in (half_width, y1 - y0, length)]
    msh = mesh.create_box(comm, [[0.0, y0, 0.0], [half_width, y1, length]], n,
                          mesh.CellType.tetrahedron)
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local
                      + msh.topology.index_map(tdim).num_ghosts, dtype=np.int32)
    y = mesh.compute_midpoints(msh, tdim, cells)[:, 1]
    tops = np.array([top for _, top in LAYERS])
    regions = np.array([CELL_TAGS[name] for name, _ in LAYERS])[np.searchsorted(tops, y)]
    cell_tags = mesh.meshtags(msh, tdim, cells, regions.astype(np.int32))
    facet_tags = mesh.meshtags(msh, tdim - 1, *_block_facets(msh, y0, y1, centre_half_width))
    names = {**CELL_TAGS, **{k: FACET_TAGS_3D[k] for k in (
        "pulp_surface", "outer_surface", "nail_centre", "symmetry", "proximal_cut")}}
    return FingertipMesh(msh, cell_tags, facet_tags, names)


def _block_facets(msh, y0: float, y1: float, centre_half_width: float):
    """(sorted exterior facets, their tags) of `layered_block`."""
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, fdim + 1)
    facets = mesh.exterior_facet_indices(msh.topology)
    x = mesh.compute_midpoints(msh, fdim, facets)
    tags = np.full(len(facets), FACET_TAGS_3D["outer_surface"], dtype=np.int32)
    for name, on in (("symmetry", np.isclose(x[:, 0], 0.0)),
                     ("proximal_cut", np.isclose(x[:, 2], 0.0)),
                     ("pulp_surface", np.isclose(x[:, 1], y0)),
                     ("nail_centre", np.isclose(x[:, 1], y1) & (x[:, 0] < centre_half_width))):
        tags[on] = FACET_TAGS_3D[name]
    return facets.astype(np.int32), tags
