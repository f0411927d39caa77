"""Pictures of meshes: the tagged regions and boundaries, drawn with matplotlib (no display)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # file output only: no display on clusters and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from dolfinx.mesh import CellType, entities_to_geometry  # noqa: E402
from matplotlib.collections import LineCollection, PolyCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from .mesh import CELL_TAGS, FACET_TAGS, FingertipMesh  # noqa: E402

REGION_COLOURS = {
    "skin": "#e8a98c", "subcutaneous": "#f6e3a1", "bone": "#d9d9d9", "nail": "#a9cbe8",
}
FACET_COLOURS = {
    "pulp_surface": "#d62728",
    "outer_surface": "#7f7f7f",
    "nail_surface": "#1f77b4",
    "nail_centre": "#2ca02c",
    "skin_subcutaneous": "#ff7f0e",
    "subcutaneous_bone": "#9467bd",
    "subcutaneous_nail": "#8c564b",
    "skin_nail": "#17becf",
}


def _owned_entities(fm: FingertipMesh, tags) -> tuple[np.ndarray, np.ndarray]:
    """(coordinates (n, k, 2), tag values) of the owned tagged entities, gathered on rank 0."""
    mesh = fm.mesh
    owned = tags.indices < mesh.topology.index_map(tags.dim).size_local
    nodes = entities_to_geometry(mesh, tags.dim, tags.indices[owned])
    if tags.dim == 2 and mesh.topology.cell_type == CellType.quadrilateral:
        nodes = nodes[:, [0, 1, 3, 2]]  # DOLFINx's tensor-product order -> around the cell
    local = (mesh.geometry.x[nodes][..., :2], tags.values[owned])
    gathered = mesh.comm.gather(local, root=0)
    if mesh.comm.rank != 0:
        return np.empty((0, nodes.shape[1], 2)), np.empty(0, dtype=np.int32)
    return np.concatenate([g[0] for g in gathered]), np.concatenate([g[1] for g in gathered])


def plot_tagged_mesh(fm: FingertipMesh, path: str | Path, title: str | None = None) -> Path | None:
    """Draw the cell regions and the facet tags: the whole section and a zoom on the pulp.

    Collective (every rank must call it); rank 0 writes `path` and returns it.
    """
    fm.mesh.topology.create_connectivity(fm.mesh.topology.dim - 1, 0)
    cells, cell_values = _owned_entities(fm, fm.cell_tags)
    facets, facet_values = _owned_entities(fm, fm.facet_tags)
    if fm.mesh.comm.rank != 0:
        return None

    region_of = {tag: name for name, tag in CELL_TAGS.items()}
    facet_of = {tag: name for name, tag in FACET_TAGS.items()}
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 5.4), width_ratios=[1.15, 1])
    for ax in axes:
        ax.add_collection(PolyCollection(
            cells, facecolors=[REGION_COLOURS[region_of[v]] for v in cell_values],
            edgecolors="k", linewidths=0.15,
        ))
        ax.add_collection(LineCollection(
            facets, colors=[FACET_COLOURS[facet_of[v]] for v in facet_values], linewidths=1.8,
        ))
        # The held patch is tiny at this scale: mark it.
        top = facets[facet_values == FACET_TAGS["nail_centre"]].reshape(-1, 2)
        if len(top):
            ax.plot(*top.mean(axis=0), "o", color=FACET_COLOURS["nail_centre"], ms=5)
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    axes[0].autoscale_view()
    axes[0].set_title(title or "fingertip section: regions and boundary tags")
    # Zoom where indenters act: the thin skin and the fine elements under the pulp.
    y_pulp = cells[..., 1].min()
    axes[1].set_xlim(-2.5, 2.5)
    axes[1].set_ylim(y_pulp - 0.2, y_pulp + 2.8)
    axes[1].set_title("pulp, under the indenters (zoom)")

    present_regions = {region_of[v] for v in np.unique(cell_values)}
    present_facets = {facet_of[v] for v in np.unique(facet_values)}
    handles = [
        Patch(facecolor=REGION_COLOURS[n], edgecolor="k", label=f"{n} ({t})")
        for n, t in CELL_TAGS.items() if n in present_regions
    ] + [
        Line2D([], [], color=FACET_COLOURS[n], lw=2.5, label=f"{n} ({t})")
        for n, t in FACET_TAGS.items() if n in present_facets
    ]
    fig.legend(handles=handles, loc="center right", frameon=False)
    fig.tight_layout(rect=(0, 0, 0.8, 1))
    path = Path(path)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path
