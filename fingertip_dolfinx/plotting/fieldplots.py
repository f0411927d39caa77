"""Field pictures with pyvista (off-screen): a scalar field on the deformed section.

`plot_field` draws the whole section at its current position (nodes moved by the displacement,
mm), coloured by one scalar field (a displacement component in mm, the pore pressure in MPa, a
strain, ...), with thin black outlines of the regions and of the outer boundary, and the rigid
indenters in place as filled grey shapes: the picture of Fig. 4 of Wu et al. (2004), the
deformed fingertip cross-section with the wedge pressed into the pulp.

Colours span the field's full range unless `saturate` is given and the field has an outlier
(a near-singular peak at a sharp tip); then they stop at an area quantile, and the picture
marks and states the true extreme (`ColourScale`, `colour_scale`). Small values are shown in a
smaller unit (kPa, Pa, µm: `figures.display_unit`).

Everything is drawn with linear cells at the mesh's geometry nodes: a P2 field or displacement
is shown by its values at the vertices. Collective: every rank sends the cells it owns to rank
0, which renders alone and writes the PNG.

Usage (a FingertipProblem `p` at time t; the indenters at their current tips)::

    tips = [(o.indenter, float(o.y_tip.value)) for o in p.obstacles]
    plot_field(p.mesh, p.fmesh.cell_tags, p.u, p.u.sub(1), "u2.png", label="u2 (mm)",
               indenters=tips)
    plot_field(p.mesh, p.fmesh.cell_tags, p.u, p.p, "p.png", label="p (MPa)",
               indenters=tips, field_mesh_nodes=p.submesh_nodes)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path

import basix
import numpy as np
import pyvista as pv
from dolfinx import fem, plot
from dolfinx import mesh as dmesh
from matplotlib import font_manager
from matplotlib.ticker import MaxNLocator

from ..geometry.indenters import Indenter
from .figures import SMALLER_UNITS, display_unit, unit_of

# Off-screen rendering needs no display: VTK first tries X, fails, says so on stderr at every
# render ("bad X server connection"), then renders off-screen anyway. Keep its errors only.
pv.OFF_SCREEN = True
try:
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
except ImportError:  # an older VTK without vtkLogger: the warning stays, harmlessly
    pass

#: Picture size in pixels (width, height).
WINDOW_SIZE = (1600, 1200)
#: The font of the pictures' titles and captions: matplotlib's DejaVu Sans, as on the curves.
#: VTK's own "arial" draws square brackets as round ones, so a title "indenters=[cylinder
#: r=5]" read "indenters=(cylinder r=5)", not the override given.
TEXT_FONT = font_manager.findfont("DejaVu Sans")
#: The longest caption drawn at 14 points (characters).
CAPTION_CHARACTERS = 100
#: Share of the picture's height given to the colour bar below the section.
BAR_SHARE = 0.13
#: Where the window goes inside the upper part (fractions: left, right, bottom, top); the top
#: is lower when there is a title.
CONTENT_BOX = (0.03, 0.97, 0.03, 0.97)
TITLED_TOP = 0.91
#: The section where the field has no value (outside a submesh), and the indenters.
BODY_GREY = "#d9d9d9"
INDENTER_GREY = "#808080"
#: Grid cells across the indenter grid (its zero level set is drawn with this resolution).
INDENTER_GRID_CELLS = 800
_VTK_TYPE = {dmesh.CellType.triangle: pv.CellType.TRIANGLE,
             dmesh.CellType.quadrilateral: pv.CellType.QUAD}


@dataclass
class _Piece:
    """Linear cells owned by one rank, ready to be joined with the other ranks' pieces on rank 0.

    `ids` number the local nodes globally (nodes shared between ranks are joined by them);
    `points` are their deformed positions (mm); `cells` index the local nodes in VTK order.
    """

    ids: np.ndarray  # (m,)
    points: np.ndarray  # (m, 2)
    cells: np.ndarray  # (n, k)
    vtk_type: int
    point_data: dict[str, np.ndarray] = dataclass_field(default_factory=dict)
    cell_data: dict[str, np.ndarray] = dataclass_field(default_factory=dict)


def plot_field(
    msh: dmesh.Mesh,
    cell_tags: dmesh.MeshTags,
    u: fem.Function,
    field: fem.Function | np.ndarray,
    path: str | Path,
    *,
    label: str,
    title: str = "",
    indenters: Sequence[tuple[Indenter, float]] = (),
    window: tuple[tuple[float, float], tuple[float, float]] | None = None,
    field_mesh_nodes: np.ndarray | None = None,
    cmap: str = "viridis",
    saturate: float | None = None,
) -> ColourScale | None:
    """Draw `field` on the section deformed by `u` and write a PNG to `path`. Collective.

    msh, cell_tags: the 2D mesh (triangles or quadrilaterals, affine geometry) and its region
        tags; region boundaries and the outer boundary are outlined in black.
    u: the displacement (mm), a vector Lagrange function (degree 1 or 2) on `msh`.
    field: the scalar to colour by, one of
        - a Lagrange (P1, P2) or DG (DG0, DG1, ...) function on `msh`;
        - a Lagrange function on a submesh of `msh` (e.g. the pore pressure, MPa, on the
          subcutaneous cells): pass `field_mesh_nodes`, the 4th return of
          `dolfinx.mesh.create_submesh` (submesh geometry node -> `msh` geometry node); the
          rest of the section is drawn in light grey;
        - a numpy array of values at `msh`'s local geometry nodes (`msh.geometry.x` rows).
    label: colour-bar title, with units ("u2 (mm)", "p (MPa)"); MPa and mm are shown in a
        smaller unit (kPa, Pa, µm) when the values are small, other units with a power of 10.
    indenters: (Indenter, y_tip) pairs, y_tip in mm; drawn filled grey where φ < 0.
    window: ((xmin, xmax), (ymin, ymax)) in mm; default: the deformed section and the top of
        the indenters.
    cmap: a matplotlib colour map name.
    saturate: if given (e.g. 0.995), the colour range may stop at the area quantiles
        1 − saturate and saturate, so that a near-singular peak at a sharp tip does not turn
        the rest of the section into one colour; an end is cut only where the values beyond
        it would take more than SATURATION_GAIN − 1 times the colours of the rest
        (`ColourScale`). Where colours saturate, the true extreme is marked on the map (a
        marker and its value), and the colour bar says so (an end swatch, and the value and
        place of the extreme in its caption).

    Returns the `ColourScale` on rank 0, None on other ranks.
    """
    section, own = _pieces(msh, cell_tags, u, field, field_mesh_nodes)
    section_grid = _gather(msh.comm, section)
    field_grid = section_grid if own is None else _gather(msh.comm, own)
    if msh.comm.rank != 0:
        return None
    scale = colour_scale(field_grid, saturate)
    if window is None:
        window = _default_window(section_grid.bounds, indenters)
    _render(section_grid, field_grid, scale, indenters, window, Path(path),
            label=label, title=title, cmap=cmap)
    return scale


#: An end of the colour range is cut at its area quantile only if the full range is more than
#: this many times the range the cut leaves: below it, the full range is readable as it is.
SATURATION_GAIN = 2.0


@dataclass
class Extreme:
    """A value of the drawn field beyond the colour range: its value and where it is drawn
    (x, y in mm, on the deformed section)."""

    kind: str  # "max" or "min"
    value: float
    x: float
    y: float


@dataclass
class ColourScale:
    """The colour range of a field picture and the extremes beyond it (marked on the map).

    low, high: the colour map's range (field units); `extremes`: the drawn field's max (min)
    when it lies above `high` (below `low`), else none. So the picture states the field's true
    range: [min, max] = [extreme "min" or low, extreme "max" or high].
    """

    low: float
    high: float
    extremes: list[Extreme] = dataclass_field(default_factory=list)

    @property
    def range(self) -> tuple[float, float]:
        return self.low, self.high

    def shown(self, kind: str) -> float:
        """The field's max ("max") or min ("min") as the picture states it."""
        marked = [e.value for e in self.extremes if e.kind == kind]
        return marked[0] if marked else (self.high if kind == "max" else self.low)


def colour_scale(grid: pv.UnstructuredGrid, saturate: float | None) -> ColourScale:
    """The colour range of `grid`'s field (see plot_field's `saturate`) and the extremes that
    lie beyond it, with the place where each is drawn."""
    values, points = _drawn_values(grid)
    low, high = float(np.nanmin(values)), float(np.nanmax(values))
    if saturate is None or high <= low:
        return ColourScale(low, high)
    q_low, q_high = _area_quantiles(grid, (1 - saturate, saturate))
    cut_low = (q_high - low) > SATURATION_GAIN * (q_high - q_low)
    cut_high = (high - q_low) > SATURATION_GAIN * (q_high - q_low)
    scale = ColourScale(q_low if cut_low else low, q_high if cut_high else high)
    for kind, cut, index in (("min", cut_low, np.nanargmin(values)),
                             ("max", cut_high, np.nanargmax(values))):
        if cut:
            x, y = points[index, :2]
            scale.extremes.append(Extreme(kind, float(values[index]), float(x), float(y)))
    return scale


def _drawn_values(grid: pv.UnstructuredGrid) -> tuple[np.ndarray, np.ndarray]:
    """The field's values as drawn and where: at the nodes (point data) or the cell centres."""
    if "field" in grid.point_data:
        return np.asarray(grid.point_data["field"], dtype=float), np.asarray(grid.points)
    return (np.asarray(grid.cell_data["field"], dtype=float),
            np.asarray(grid.cell_centers().points))


# --- data: values at the geometry nodes, one piece per rank -------------------------------------


def _area_quantiles(grid: pv.UnstructuredGrid, qs) -> tuple[float, ...]:
    """Quantiles of the field over the section's AREA (cell means weighted by cell area):
    node-counted quantiles would be ruled by the refined zones, where the nodes crowd."""
    cells = grid.point_data_to_cell_data() if "field" in grid.point_data else grid
    values = np.asarray(cells.cell_data["field"], dtype=float)
    area = np.abs(np.asarray(cells.compute_cell_sizes(length=False, volume=False)
                             .cell_data["Area"]))
    keep = np.isfinite(values)
    order = np.argsort(values[keep])
    cumulative = np.cumsum(area[keep][order]) / area[keep].sum()
    return tuple(float(values[keep][order][np.searchsorted(cumulative, q)]) for q in qs)


def _pieces(msh, cell_tags, u, field, field_mesh_nodes) -> tuple[_Piece, _Piece | None]:
    """The section's piece (region tags, and the field if it lives on its nodes or cells) and
    the field's own piece when it has other nodes (a submesh, a discontinuous field)."""
    _check_mesh(msh)
    node_disp = _node_values(u)
    section = _section_piece(msh, cell_tags, node_disp)
    if field_mesh_nodes is not None:
        return section, _submesh_piece(field, section.points, field_mesh_nodes)
    if isinstance(field, np.ndarray):
        if field.shape != (len(section.ids),):
            raise ValueError(f"field: {field.shape} values given, the mesh has "
                             f"{len(section.ids)} local geometry nodes.")
        section.point_data["field"] = np.asarray(field, dtype=float)
        return section, None
    element = _scalar_lagrange(field)
    if field.function_space.mesh.topology.index_map(2).size_global != (
            msh.topology.index_map(2).size_global):
        raise ValueError("field: lives on another mesh; for a submesh pass field_mesh_nodes.")
    if not element.discontinuous:
        section.point_data["field"] = _node_values(field)[:, 0]
    elif element.degree == 0:
        owned = msh.topology.index_map(2).size_local
        section.cell_data["field"] = field.x.array[field.function_space.dofmap.list[:owned, 0]]
    else:
        return section, _dg_piece(field, node_disp)
    return section, None


def _check_mesh(msh: dmesh.Mesh):
    """Only straight-sided triangles and quadrilaterals in 2D are drawn."""
    if msh.topology.cell_type not in _VTK_TYPE or msh.geometry.cmaps[0].degree != 1:
        raise ValueError(f"plot_field draws affine triangles or quadrilaterals, not "
                         f"{msh.topology.cell_name()} cells of degree "
                         f"{msh.geometry.cmaps[0].degree}.")


def _scalar_lagrange(f: fem.Function):
    """The element of `f`, checked to be scalar (continuous or discontinuous) Lagrange."""
    element = f.function_space.ufl_element()
    if f.function_space.value_shape != () or element.element_family != basix.ElementFamily.P:
        raise ValueError(f"field {f.name!r}: a scalar Lagrange or DG function is needed.")
    return element


def _node_values(f: fem.Function) -> np.ndarray:
    """A Lagrange function's values at its mesh's local geometry nodes, shape (nodes, size).

    Interpolated into P1 first (exact at the vertices for P1 and P2), whose cell dofs are in the
    same order as the cells' geometry nodes.
    """
    msh = f.function_space.mesh
    shape = f.function_space.value_shape
    P1 = fem.functionspace(msh, ("Lagrange", 1, shape) if shape else ("Lagrange", 1))
    f1 = fem.Function(P1)
    f1.interpolate(f)
    bs = P1.dofmap.index_map_bs
    values = np.zeros((msh.geometry.x.shape[0], bs))
    nodes = msh.geometry.dofmaps[0]
    values[nodes.ravel()] = f1.x.array.reshape(-1, bs)[P1.dofmap.list.ravel()]
    return values


def _cells_piece(msh: dmesh.Mesh, points: np.ndarray) -> _Piece:
    """The owned cells of `msh` at the node positions `points` (local geometry nodes, mm)."""
    owned = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    topology, _, _ = plot.vtk_mesh(msh, 2, owned)
    k = msh.geometry.dofmaps[0].shape[1]
    ids = msh.geometry.index_map().local_to_global(np.arange(len(points), dtype=np.int32))
    return _Piece(ids, points, topology.reshape(-1, k + 1)[:, 1:],
                  _VTK_TYPE[msh.topology.cell_type])


def _section_piece(msh, cell_tags, node_disp: np.ndarray) -> _Piece:
    """The whole section, deformed, with each owned cell's region tag (-1: untagged)."""
    piece = _cells_piece(msh, msh.geometry.x[:, :2] + node_disp)
    owned = len(piece.cells)
    region = np.full(owned, -1, dtype=np.int32)
    mine = cell_tags.indices < owned
    region[cell_tags.indices[mine]] = cell_tags.values[mine]
    piece.cell_data["region"] = region
    return piece


def _submesh_piece(field: fem.Function, parent_points, field_mesh_nodes) -> _Piece:
    """A Lagrange field on a submesh, its nodes moved with their parent nodes."""
    _scalar_lagrange(field)
    submesh = field.function_space.mesh
    if field.function_space.ufl_element().discontinuous:
        raise ValueError(f"field {field.name!r}: only continuous fields on a submesh.")
    if len(field_mesh_nodes) != submesh.geometry.x.shape[0]:
        raise ValueError("field_mesh_nodes: one parent node per submesh geometry node needed "
                         "(the 4th return of create_submesh).")
    piece = _cells_piece(submesh, parent_points[np.asarray(field_mesh_nodes)])
    piece.point_data["field"] = _node_values(field)[:, 0]
    return piece


def _dg_piece(field: fem.Function, node_disp: np.ndarray) -> _Piece:
    """A discontinuous field as DG1: every cell has its own corners (the DG1 dofs)."""
    msh = field.function_space.mesh
    DG1 = fem.functionspace(msh, ("DG", 1))
    f1 = fem.Function(DG1)
    f1.interpolate(field)
    owned = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    topology, _, x = plot.vtk_mesh(DG1, owned)
    # DG1 dofs sit at the cell's vertices in the order of its geometry nodes.
    disp = np.zeros((len(x), 2))
    disp[DG1.dofmap.list.ravel()] = node_disp[msh.geometry.dofmaps[0].ravel()]
    index_map = DG1.dofmap.index_map
    ids = index_map.local_to_global(np.arange(len(x), dtype=np.int32))
    k = DG1.dofmap.list.shape[1]
    return _Piece(ids, x[:, :2] + disp, topology.reshape(-1, k + 1)[:, 1:],
                  _VTK_TYPE[msh.topology.cell_type], point_data={"field": f1.x.array.copy()})


def _gather(comm, piece: _Piece) -> pv.UnstructuredGrid | None:
    """Join the ranks' pieces on rank 0 (shared nodes once, by global id); None elsewhere."""
    pieces = comm.gather(piece, root=0)
    if comm.rank != 0:
        return None
    ids = np.concatenate([p.ids for p in pieces])
    unique, compact = np.unique(ids, return_inverse=True)
    starts = np.cumsum([0] + [len(p.ids) for p in pieces[:-1]])
    cells = np.concatenate([compact[start + p.cells] for start, p in zip(starts, pieces)])
    points = np.zeros((len(unique), 3))
    points[compact, :2] = np.concatenate([p.points for p in pieces])
    grid = pv.UnstructuredGrid({piece.vtk_type: cells}, points)
    for name in piece.point_data:
        values = np.zeros(len(unique))
        values[compact] = np.concatenate([p.point_data[name] for p in pieces])
        grid.point_data[name] = values
    for name in piece.cell_data:
        grid.cell_data[name] = np.concatenate([p.cell_data[name] for p in pieces])
    return grid


# --- drawing (rank 0) -----------------------------------------------------------------------------


def _default_window(bounds, indenters) -> tuple[tuple[float, float], tuple[float, float]]:
    """The deformed section (bounds of its grid) and the top fifth of its height below it, where
    the indenters are seen; 2 % of the size around."""
    xmin, xmax, ymin, ymax = bounds[:4]
    if indenters:
        ymin = min(ymin, min(y for _, y in indenters) - 0.2 * (ymax - ymin))
    pad = 0.02 * max(xmax - xmin, ymax - ymin)
    return (xmin - pad, xmax + pad), (ymin - pad, ymax + pad)


def _outline(grid: pv.UnstructuredGrid) -> pv.PolyData:
    """The cell edges between different regions and on the outer boundary, as line segments."""
    cells = grid.cells_dict[next(iter(grid.cells_dict))]
    k = cells.shape[1]
    edges = np.sort(np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1)
    region = np.repeat(grid.cell_data["region"], k)
    unique, index, count = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    low = np.full(len(unique), np.iinfo(np.int32).max)
    high = np.full(len(unique), np.iinfo(np.int32).min)
    np.minimum.at(low, index.ravel(), region)
    np.maximum.at(high, index.ravel(), region)
    keep = unique[(count == 1) | (low != high)]
    lines = np.column_stack([np.full(len(keep), 2), keep]).ravel()
    return pv.PolyData(grid.points, lines=lines)


def _indenter_shapes(indenters, window) -> pv.UnstructuredGrid | None:
    """The indenters (φ < 0) over the window, cut from a grid of the signed distance φ (mm)."""
    (x0, x1), (y0, y1) = window
    h = max(x1 - x0, y1 - y0) / INDENTER_GRID_CELLS
    n = (int(np.ceil((x1 - x0) / h)) + 1, int(np.ceil((y1 - y0) / h)) + 1, 1)
    grid = pv.ImageData(dimensions=n, spacing=(h, h, 1.0), origin=(x0, y0, 0.0))
    grid.point_data["phi"] = np.min(
        [ind.signed_distance_np(grid.points, y_tip)[0] for ind, y_tip in indenters], axis=0)
    inside = grid.clip_scalar(scalars="phi", value=0.0, invert=True)
    return inside if inside.n_cells else None


def _frame(renderer, window, aspect: float, top: float):
    """Parallel 2D view (looking down -z, x right, y up) fitting `window` into CONTENT_BOX (up to
    `top`) of a renderer of width/height `aspect`; returns the view's half width, height (mm)."""
    (x0, x1), (y0, y1) = window
    left, right, bottom, _ = CONTENT_BOX
    half_h = max((y1 - y0) / (2 * (top - bottom)), (x1 - x0) / (2 * (right - left) * aspect))
    half_w = half_h * aspect
    fx = 0.5 * (x0 + x1) + half_w * (1 - (left + right))
    fy = 0.5 * (y0 + y1) + half_h * (1 - (bottom + top))
    camera = renderer.camera
    camera.parallel_projection = True
    camera.focal_point = (fx, fy, 0.0)
    camera.position = (fx, fy, 10.0 * max(half_w, half_h))
    camera.up = (0.0, 1.0, 0.0)
    camera.parallel_scale = half_h
    renderer.reset_camera_clipping_range()
    return half_w, half_h


def _render(section_grid, field_grid, scale: ColourScale, indenters, window, path: Path, *,
            label, title, cmap):
    """Draw back to front (grey section, field, indenters, outlines, marked extremes) and
    write the PNG; the field in the unit `figures.display_unit` chooses."""
    original = label
    factor, label = display_unit(label, max(abs(scale.low), abs(scale.high)))
    field_grid["shown"] = field_grid["field"] * factor
    shown = _shown_range((factor * scale.low, factor * scale.high))
    plotter = pv.Plotter(off_screen=True, window_size=list(WINDOW_SIZE), shape=(2, 1),
                         row_weights=[1 - BAR_SHARE, BAR_SHARE], border=False)
    try:
        plotter.set_background("white")
        plotter.subplot(0, 0)
        draw = _Layers(plotter, window)
        if field_grid is not section_grid:
            draw.add(section_grid, color=BODY_GREY)
        field = draw.add(field_grid, scalars="shown", cmap=cmap, clim=shown,
                         show_scalar_bar=False)
        if indenters:
            draw.add(_indenter_shapes(indenters, window), color=INDENTER_GREY)
        draw.add(_outline(section_grid), color="black", line_width=1.5)
        notes = _mark_extremes(plotter, draw, scale.extremes, original)
        if title:
            _text(plotter, title, position="upper_edge", font_size=14, color="black")
        aspect = WINDOW_SIZE[0] / (WINDOW_SIZE[1] * (1 - BAR_SHARE))
        half_w, half_h = _frame(plotter.renderer, window, aspect,
                                TITLED_TOP if title else CONTENT_BOX[3])
        plotter.subplot(1, 0)
        _scale_bar(plotter, half_w, half_h * BAR_SHARE / (1 - BAR_SHARE))
        if field is not None:  # else no part of the field is in the window
            _colour_bar(plotter, field.mapper, label, shown, scale.extremes, notes)
        plotter.screenshot(str(path))
    finally:
        plotter.close()


def value_text(label: str, value: float) -> str:
    """A value of the field labelled `label` in its own readable unit ("20.1 kPa", "268 Pa");
    a strain as it is ("-0.325", "-3.25e-04")."""
    unit = unit_of(label)
    if unit in SMALLER_UNITS:
        factor, shown = display_unit(label, abs(value))
        return f"{_number(factor * value)} {unit_of(shown)}"
    return f"{_number(value)} {'' if unit == '-' else unit}".rstrip()


def _mark_extremes(plotter, draw, extremes: list[Extreme], label: str) -> list:
    """A marker and a label "max 33 Pa" on the map at each extreme beyond the colour range;
    returns the captions for the colour bar ("max 33 Pa at (0.21, -6.80) mm")."""
    notes = []
    (x0, x1), (y0, y1) = draw.window
    offset = 0.015 * max(x1 - x0, y1 - y0)  # the label up and right of the marker
    for e in extremes:
        value = f"{e.kind} {value_text(label, e.value)}"
        rings = (((0.5, 1.3), "white"), ((0.7, 1.1), "black"), ((0.0, 0.25), "black"))
        for radii, colour in rings:  # a ring with a dot, outlined in white: seen on any colour
            draw.z += draw.dz
            plotter.add_mesh(pv.Disc(center=(e.x, e.y, draw.z), inner=radii[0] * offset / 2,
                                     outer=radii[1] * offset / 2, c_res=48), color=colour,
                             lighting=False)
        plotter.add_point_labels(np.array([[e.x + offset, e.y + offset, draw.z]]), [value],
                                 font_size=22, text_color="black", show_points=False,
                                 shape_color="white", shape_opacity=0.85, margin=4,
                                 always_visible=True)
        notes.append(f"{value} at ({e.x:.2f}, {e.y:.2f}) mm")
    return notes


def caption_size(caption: str) -> int:
    """The colour bar's caption's font size: 14 points, smaller for a caption that would
    not fit across the picture (the label and both extremes: ~130 characters; DejaVu Sans at
    14 points takes ~14 px a character of the 1600 px)."""
    return max(9, min(14, int(14 * CAPTION_CHARACTERS / max(len(caption), 1))))


def _text(plotter, text: str, **options):
    """`plotter.add_text` in TEXT_FONT (brackets drawn as brackets); returns the actor."""
    return plotter.add_text(text, font_file=TEXT_FONT, **options)


def _number(value: float) -> str:
    """Three significant digits (an exponent only below 1e-3 or from 1e4)."""
    return f"{value:.3g}" if value == 0 or 1e-3 <= abs(value) < 1e4 else f"{value:.2e}"


class _Layers:
    """Flat layers cut to the window, each added a little in front of the ones before (z)."""

    def __init__(self, plotter, window):
        self.plotter, self.window, self.z = plotter, window, 0.0
        self.dz = 1e-3 * max(window[0][1] - window[0][0], window[1][1] - window[1][0])

    def add(self, dataset, **options):
        """Add the part of `dataset` inside the window; returns its actor (None if empty)."""
        if dataset is None:
            return None
        (x0, x1), (y0, y1) = self.window
        inside = dataset.clip_box((x0, x1, y0, y1, -1.0, 1.0), invert=False)
        if inside.n_cells == 0:
            return None
        inside.points[:, 2] = self.z
        self.z += self.dz
        return self.plotter.add_mesh(inside, lighting=False, **options)


def _scale_bar(plotter, half_w: float, half_h: float):
    """A round length (1, 2 or 5 x 10^k mm) at the left of the current (lower) renderer, drawn
    to the scale of the section above: same width `2 half_w` (mm), height `2 half_h` (mm)."""
    camera = plotter.renderer.camera
    camera.parallel_projection = True
    camera.focal_point, camera.position, camera.up = (0, 0, 0), (0, 0, 1), (0, 1, 0)
    camera.parallel_scale = half_h
    width = 2 * half_w
    e = int(np.floor(np.log10(0.1 * width)))
    length = max(m * 10.0**k for k in (e - 1, e) for m in (1, 2, 5) if m * 10.0**k <= 0.1 * width)
    start = np.array([-half_w + 0.025 * width, -0.2 * half_h, 0.0])
    plotter.add_mesh(pv.Line(start, start + [length, 0.0, 0.0]), color="black", line_width=5,
                     lighting=False)
    plotter.renderer.reset_camera_clipping_range()
    centre = 0.025 + 0.5 * length / width
    text = _text(plotter, f"{length:g} mm", position=(centre, 0.5), viewport=True,
                 font_size=12, color="black")
    text.GetTextProperty().SetJustificationToCentered()


def _shown_range(clim) -> tuple[float, float]:
    """The colour map's range: `clim`, with round-off zeros made 0 (the bar says 0, not
    -4e-19) and widened if the field is constant."""
    span = clim[1] - clim[0]
    if span <= 0:
        return clim[0] - 0.5, clim[1] + 0.5
    return tuple(0.0 if abs(c) < 1e-9 * span else c for c in clim)


def _ticks(low: float, high: float) -> tuple[np.ndarray, str]:
    """Round tick values inside [low, high] and the printf format that writes them exactly."""
    ticks = MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]).tick_values(low, high)
    span = high - low
    ticks = ticks[(ticks >= low - 1e-9 * span) & (ticks <= high + 1e-9 * span)]
    step = ticks[1] - ticks[0] if len(ticks) > 1 else span
    digits = next((d for d in range(10)
                   if np.allclose(np.round(ticks, d), ticks, rtol=0, atol=1e-6 * step)), None)
    return ticks, ("%.3g" if digits is None else f"%.{digits}f")  # %.3g: tiny values


def _colour_bar(plotter, mapper, label: str, shown, extremes: list[Extreme], notes: list):
    """A horizontal colour bar across the current (lower) renderer: bar, ticks, then `label`;
    an end swatch where colours saturate, and the extremes beyond it in the caption."""
    ticks, fmt = _ticks(*shown)
    kinds = {e.kind for e in extremes}
    lut = mapper.lookup_table
    if "max" in kinds:
        lut.above_range_color = lut.GetTableValue(lut.GetNumberOfTableValues() - 1)[:3]
    if "min" in kinds:
        lut.below_range_color = lut.GetTableValue(0)[:3]
    bar = plotter.add_scalar_bar(
        title=label, mapper=mapper, vertical=False, position_x=0.17, position_y=0.4,
        width=0.7, height=0.58, color="black", label_font_size=22, fmt=fmt,
        unconstrained_font_size=True, above_label="" if "max" in kinds else None,
        below_label="" if "min" in kinds else None)
    bar.SetTitle("")  # written below instead: VTK puts a horizontal bar's title on its labels
    bar.SetUseCustomLabels(True)
    bar.SetCustomLabels(pv.convert_array(ticks))
    bar.SetTextPositionToPrecedeScalarBar()  # the tick labels under the bar
    bar.SetBarRatio(0.45)
    caption = label if not notes else (
        f"{label}; colours saturate beyond the bar: " + ", ".join(notes))
    text = _text(plotter, caption, position=(0.52, 0.08), viewport=True,
                 font_size=caption_size(caption), color="black")
    text.GetTextProperty().SetJustificationToCentered()


# --- the tagged 3D mesh -----------------------------------------------------------------------


def plot_tagged_mesh3d(fm, path: Path, title: str | None = None) -> Path | None:
    """A 3D mesh's tags in two views: the exposed surface coloured by facet tag (seen from the
    palmar side), and the cells behind the mid-sagittal plane x = 0 coloured by region (seen
    from -x: the layers skin, subcutaneous tissue, bone and nail in section).

    Collective (every rank must call it); rank 0 writes `path` and returns it.
    """
    from ..geometry.mesh import CELL_TAGS, FACET_TAGS_3D
    from .figures import FACET_COLOURS, REGION_COLOURS

    cells, cell_values = _gather_entities(fm, fm.cell_tags)
    facets, facet_values = _gather_entities(fm, fm.facet_tags)
    if fm.mesh.comm.rank != 0:
        return None
    colours = FACET_COLOURS | {"symmetry": "#bcbd22", "proximal_cut": "#e377c2"}
    exposed = facet_values < 20  # tags 11-16; interfaces are 21-24
    surface = _coloured(facets[exposed], pv.CellType.TRIANGLE, facet_values[exposed],
                        {t: colours[n] for n, t in FACET_TAGS_3D.items()})
    behind = cells[..., 0].mean(axis=1) >= 0.0  # cells with centroid x >= 0: a crinkled cut
    section = _coloured(cells[behind], pv.CellType.TETRA, cell_values[behind],
                        {t: REGION_COLOURS[n] for n, t in CELL_TAGS.items()})
    plotter = pv.Plotter(off_screen=True, window_size=[1800, 900], shape=(1, 2))
    plotter.add_mesh(surface, scalars="colour", rgb=True, show_edges=True, line_width=0.3)
    plotter.view_vector((1.0, -0.35, 0.7), viewup=(0, 1, 0))  # the side (x > 0), pulp, tip
    present = {n for n, t in FACET_TAGS_3D.items() if t in set(facet_values[exposed])}
    _swatch_legend(plotter, [(n, colours[n]) for n in FACET_TAGS_3D if n in present],
                   size=(0.22, 0.22))
    _text(plotter, title or "3D fingertip: boundary tags", font_size=11, position="upper_right")
    plotter.subplot(0, 1)
    plotter.add_mesh(section, scalars="colour", rgb=True, show_edges=True, line_width=0.3,
                     lighting=False)
    plotter.view_vector((-1.0, 0.0, 0.0), viewup=(0, 1, 0))
    _swatch_legend(plotter, [(n, REGION_COLOURS[n]) for n in CELL_TAGS], size=(0.18, 0.16))
    _text(plotter, "regions, cut at x = 0 (z: proximal cut -> tip)", font_size=11,
          position="upper_right")
    plotter.screenshot(str(path))
    plotter.close()
    return Path(path)


def _swatch_legend(plotter, entries, size: tuple[float, float]) -> None:
    """A legend at the lower left of the current renderer: a colour square and the name in
    black per entry (pyvista's legend writes each name in its own colour: pale ones, the bone's
    grey or the nail's blue, are unreadable on white)."""
    from matplotlib.colors import to_rgb
    from vtkmodules.vtkRenderingAnnotation import vtkLegendBoxActor

    legend = vtkLegendBoxActor()
    legend.SetNumberOfEntries(len(entries))
    for i, (name, colour) in enumerate(entries):
        square = pv.Rectangle(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]], dtype=float))
        square.cell_data["rgb"] = np.tile(np.round(255 * np.array(to_rgb(colour))),
                                          (square.n_cells, 1)).astype(np.uint8)
        square.cell_data.active_scalars_name = "rgb"  # the square's colour; the text black
        legend.SetEntry(i, square, name, [0.0, 0.0, 0.0])
    legend.UseBackgroundOn()
    legend.SetBackgroundColor(1.0, 1.0, 1.0)
    legend.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    legend.GetPositionCoordinate().SetValue(0.02, 0.02)
    legend.GetPosition2Coordinate().SetValue(*size)
    plotter.renderer.AddActor(legend)


def _gather_entities(fm, tags) -> tuple[np.ndarray, np.ndarray]:
    """(coordinates (n, k, 3), tag values) of the owned tagged entities, gathered on rank 0."""
    mesh = fm.mesh
    mesh.topology.create_connectivity(tags.dim, mesh.topology.dim)
    owned = tags.indices < mesh.topology.index_map(tags.dim).size_local
    nodes = dmesh.entities_to_geometry(mesh, tags.dim, tags.indices[owned])
    gathered = mesh.comm.gather((mesh.geometry.x[nodes], tags.values[owned]), root=0)
    if mesh.comm.rank != 0:
        return np.empty((0, nodes.shape[1], 3)), np.empty(0, dtype=np.int32)
    return np.concatenate([g[0] for g in gathered]), np.concatenate([g[1] for g in gathered])


def _coloured(points: np.ndarray, vtk_type, values: np.ndarray, colour_of: dict):
    """An unstructured grid of separate cells (points (n, k, 3)) with an RGB cell colour."""
    from matplotlib.colors import to_rgb

    n, k = points.shape[:2]
    grid = pv.UnstructuredGrid({vtk_type: np.arange(n * k).reshape(n, k)},
                               points.reshape(-1, 3))
    rgb = np.array([to_rgb(colour_of[v]) for v in values]).reshape(-1, 3)
    grid.cell_data["colour"] = (255 * rgb).astype(np.uint8)
    return grid
