"""Field pictures (fieldplots.plot_field): colour range, pixels, indenters, submesh fields.

A rectangle [0, 2] x [0, 1] mm in two regions (x < 0.5: tag 1, x > 0.5: tag 2) is sheared by the
displacement u = (0, A x): it becomes a parallelogram and u2 = A x is known everywhere, so the
colour of a pixel can be checked against the colour map at the x it shows.
"""

import numpy as np
import pytest
from dolfinx import fem
from dolfinx import mesh as dmesh
from matplotlib import colormaps
from matplotlib.colors import to_rgb
from mpi4py import MPI
from PIL import Image

from fingertip_dolfinx.geometry.indenters import Cylinder
from fingertip_dolfinx.plotting.fieldplots import (
    BAR_SHARE,
    BODY_GREY,
    INDENTER_GREY,
    WINDOW_SIZE,
    plot_field,
)

A = 0.2  # shear: u2 = A x (mm), from 0 to 2 A across the body
X_INTERFACE = 0.5  # the regions' interface (not where two ranks' parts meet, x = 1)
RIGHT = 2  # tag of the cells with x > X_INTERFACE


def _rectangle(comm, cell_type=dmesh.CellType.triangle):
    """The two-region rectangle, its tags, u = (0, A x) in P2 and u2 in P1."""
    msh = dmesh.create_rectangle(comm, [[0.0, 0.0], [2.0, 1.0]], [16, 8], cell_type)
    cells = np.arange(msh.topology.index_map(2).size_local
                      + msh.topology.index_map(2).num_ghosts, dtype=np.int32)
    midpoints = dmesh.compute_midpoints(msh, 2, cells)
    tags = dmesh.meshtags(msh, 2, cells, np.where(midpoints[:, 0] < X_INTERFACE, 1, RIGHT)
                          .astype(np.int32))
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 2, (2,))))
    u.interpolate(lambda x: np.stack([0.0 * x[0], A * x[0]]))
    u2 = fem.Function(fem.functionspace(msh, ("Lagrange", 1)))
    u2.interpolate(lambda x: A * x[0])
    return msh, tags, u, u2


def _image(path) -> np.ndarray:
    """The picture as integers (rows, columns, RGB), only the part above the colour bar."""
    image = np.asarray(Image.open(path).convert("RGB")).astype(int)
    assert image.shape == (WINDOW_SIZE[1], WINDOW_SIZE[0], 3)
    return image[: int(WINDOW_SIZE[1] * (1 - BAR_SHARE)) - 2]


def _is(image, colour, tol=3) -> np.ndarray:
    """Mask of the pixels of one colour (matplotlib name or hex)."""
    rgb = np.array(to_rgb(colour)) * 255
    return np.all(np.abs(image - rgb) <= tol, axis=-1)


def _body_box(image, coloured=True) -> tuple[int, int, int, int]:
    """(top, bottom, left, right) pixel rows/columns of the coloured pixels (the colour map's
    colours are saturated; white, greys and black are not), or of all but white ones."""
    drawn = image.max(axis=-1) - image.min(axis=-1) > 40 if coloured else ~_is(image, "white")
    rows, cols = np.nonzero(drawn)
    return rows.min(), rows.max(), cols.min(), cols.max()


@pytest.mark.mpi
@pytest.mark.parametrize("cell_type", [dmesh.CellType.triangle, dmesh.CellType.quadrilateral])
def test_u2_range_and_colours(comm, shared_tmp_path, cell_type):
    msh, tags, u, u2 = _rectangle(comm, cell_type)
    path = shared_tmp_path / "u2.png"
    clim = plot_field(msh, tags, u, u2, path, label="u2 (mm)")
    if comm.rank != 0:
        assert clim is None
        return
    assert clim.range == pytest.approx((0.0, 2 * A), abs=1e-12)
    image = _image(path)
    top, bottom, left, right = _body_box(image)
    assert (right - left) / (bottom - top) == pytest.approx(2 / (1 + 2 * A), rel=0.01)
    # The deformed body spans x in [0, 2] and y in [0, 1 + 2A]; for y in [0.45, 0.95] mm every
    # x is inside it, and the colour at x is viridis(u2 / 2A) = viridis(x / 2): check every
    # pixel of three rows, but the black outline of the region interface (a seam between cells
    # or between the ranks' pieces would show as a mismatch).
    cols = np.arange(left + 3, right - 2)
    x = 2 * (cols - left) / (right - left)
    expected = colormaps["viridis"](x / 2)[:, :3] * 255
    off_interface = np.abs(x - X_INTERFACE) > 4 * 2 / (right - left)
    for y in (0.5, 0.7, 0.9):
        row = round(top + (bottom - top) * (1 + 2 * A - y) / (1 + 2 * A))
        error = np.abs(image[row, cols] - expected).max(axis=-1)
        assert error[off_interface].max() <= 10, (y, x[off_interface][error[off_interface] > 10])
        line = image[row, cols[~off_interface]].sum(axis=-1)  # the outline: 1.5 px, darker
        assert line.min() < 0.7 * image[row, cols[~off_interface]].sum(axis=-1).max()
    assert not _is(image, INDENTER_GREY).any()


def test_indenter_drawn_below_the_body(comm, shared_tmp_path):
    msh, tags, u, u2 = _rectangle(comm)
    path = shared_tmp_path / "indenter.png"
    cylinder = Cylinder(radius=0.5, centre_x=1.0)
    clim = plot_field(msh, tags, u, u2, path, label="u2 (mm)", title="sheared rectangle",
                      indenters=[(cylinder, -0.1)])
    if comm.rank != 0:
        return
    assert clim.range == pytest.approx((0.0, 2 * A), abs=1e-12)
    image = _image(path)[120:]  # below the title
    rows, cols = np.nonzero(_is(image, INDENTER_GREY))
    assert len(rows) > 2000
    # Below the body's lowest point (y = 0 at x = 0), centred under x = 1 (the body's middle).
    _, bottom, left, right = _body_box(image)
    assert rows.min() > bottom + 20
    assert abs(cols.mean() - 0.5 * (left + right)) < 5


def test_submesh_field(comm, shared_tmp_path):
    msh, tags, u, _ = _rectangle(comm)
    submesh, _, _, nodes = dmesh.create_submesh(msh, 2, tags.find(RIGHT))
    p = fem.Function(fem.functionspace(submesh, ("Lagrange", 1)))
    p.interpolate(lambda x: 0.01 + 0.002 * x[0] * x[1])  # a pore pressure, MPa
    path = shared_tmp_path / "p.png"
    clim = plot_field(msh, tags, u, p, path, label="p (MPa)", field_mesh_nodes=nodes)
    low = comm.allreduce(p.x.array.min(), op=MPI.MIN)
    high = comm.allreduce(p.x.array.max(), op=MPI.MAX)
    if comm.rank != 0:
        return
    assert clim.range == (low, high)
    image = _image(path)
    top, bottom, left, right = _body_box(image, coloured=False)
    row = (top + bottom) // 2
    at_x = [round(left + (right - left) * x / 2) for x in (0.25, 1.5)]
    assert _is(image[row, at_x[0]], BODY_GREY)  # x < 0.5: no pressure there, light grey
    assert not _is(image[row, at_x[1]], BODY_GREY)


@pytest.mark.parametrize("family, degree", [("DG", 0), ("DG", 1), ("Lagrange", 2)])
def test_function_fields(comm, shared_tmp_path, family, degree):
    """The range of the drawn values: cell values (DG0), corner values (DG1), vertex values
    (P2, exact here: q is linear)."""
    msh, tags, u, _ = _rectangle(comm)
    q = fem.Function(fem.functionspace(msh, (family, degree)))
    q.interpolate(lambda x: x[0] + 2 * x[1])
    clim = plot_field(msh, tags, u, q, shared_tmp_path / "q.png", label="q (-)")
    if degree == 0:  # the values at the cell centroids, inside (0, 4)
        expected = (comm.allreduce(q.x.array.min(), op=MPI.MIN),
                    comm.allreduce(q.x.array.max(), op=MPI.MAX))
        assert 0 < expected[0] < 0.5 and 3.5 < expected[1] < 4
    else:
        expected = (0.0, 4.0)
    if comm.rank == 0:
        assert clim.range == pytest.approx(expected, abs=1e-12)


def test_displacement_component(comm, shared_tmp_path):
    """u.sub(1) of the P2 displacement: u2 without a copy (the recorder's picture)."""
    msh, tags, u, _ = _rectangle(comm)
    clim = plot_field(msh, tags, u, u.sub(1), shared_tmp_path / "u2.png", label="u2 (mm)")
    if comm.rank == 0:
        assert clim.range == pytest.approx((0.0, 2 * A), abs=1e-12)


def test_node_array_field(comm, shared_tmp_path):
    msh, tags, u, _ = _rectangle(comm)
    clim = plot_field(msh, tags, u, 3.0 * msh.geometry.x[:, 1], shared_tmp_path / "y.png",
                      label="3y (mm)")
    if comm.rank == 0:
        assert clim.range == pytest.approx((0.0, 3.0), abs=1e-12)
    with pytest.raises(ValueError, match="geometry nodes"):
        plot_field(msh, tags, u, np.zeros(3), shared_tmp_path / "y.png", label="3y (mm)")


def test_rejects_a_field_on_another_mesh(comm, shared_tmp_path):
    msh, tags, u, _ = _rectangle(comm)
    other = dmesh.create_unit_square(comm, 3, 3)
    f = fem.Function(fem.functionspace(other, ("Lagrange", 1)))
    with pytest.raises(ValueError, match="another mesh"):
        plot_field(msh, tags, u, f, shared_tmp_path / "x.png", label="f")


SPIKE = (1.5, 0.5, 100.0)  # a node of the 16 x 8 grid and the value there: a near-singular peak


def _spiked(msh):
    """u2 = A x at the nodes, but SPIKE's value at its node: at the undeformed nodes."""
    x = msh.geometry.x
    at_spike = np.hypot(x[:, 0] - SPIKE[0], x[:, 1] - SPIKE[1]) < 1e-9
    return np.where(at_spike, SPIKE[2], A * x[:, 0])


@pytest.mark.mpi
def test_saturated_colours_mark_the_true_extreme(comm, shared_tmp_path):
    """A peak 250 times the rest (one node; its 6 cells hold 2.3 % of the area): the colours
    stop at the 95 % area quantile, below the rest's max 2A, and the picture states the true
    max, where it is drawn (the spike's node, moved by u)."""
    msh, tags, u, _ = _rectangle(comm)
    values = _spiked(msh)
    scale = plot_field(msh, tags, u, values, shared_tmp_path / "s.png",
                       label="sed (MPa)", saturate=0.95)
    true_max = comm.allreduce(values.max(), op=MPI.MAX)
    if comm.rank != 0:
        return
    assert scale.high < 2 * A < true_max  # saturated
    assert scale.shown("max") == pytest.approx(true_max, rel=1e-14)
    (marked,) = scale.extremes
    assert (marked.kind, marked.x, marked.y) == pytest.approx(
        ("max", SPIKE[0], SPIKE[1] + A * SPIKE[0]), abs=1e-12)
    assert scale.shown("min") == scale.low == 0.0  # no cut at the bottom: nothing beyond


def test_mild_peak_keeps_the_full_range(comm, shared_tmp_path):
    """With `saturate` but no outlier (u2 = A x: the 99.5 % range is nearly the full one),
    the colours span the field's whole range, and nothing is marked."""
    msh, tags, u, u2 = _rectangle(comm)
    scale = plot_field(msh, tags, u, u2, shared_tmp_path / "m.png", label="u2 (mm)",
                       saturate=0.995)
    if comm.rank == 0:
        assert scale.range == pytest.approx((0.0, 2 * A), abs=1e-12)
        assert scale.extremes == []


def test_saturated_colours_cover_a_share_of_the_area(comm, shared_tmp_path):
    """u2 = A x over the 2 × 1 rectangle (the shear keeps areas), with one spiked node: a
    fraction q of the area has x below 2q, so the colour range stops at 2qA, to one cell column
    (0.125 mm), however the nodes are spread; the bottom (0, not far below the 10 % quantile)
    is not cut."""
    msh, tags, u, _ = _rectangle(comm)
    scale = plot_field(msh, tags, u, _spiked(msh), shared_tmp_path / "s.png",
                       label="u2 (mm)", saturate=0.9)
    if comm.rank == 0:
        assert scale.range == pytest.approx((0.0, 2 * 0.9 * A), abs=0.125 * A)
        assert [e.kind for e in scale.extremes] == ["max"]


@pytest.mark.parametrize("peak, factor, shown", [
    (3.3e-5, 1e6, "sed (Pa)"), (8.5e-4, 1e3, "sed (kPa)"), (0.25, 1.0, "sed (MPa)"),
    (0.04, 1e3, "sed (kPa)")])
def test_small_stresses_in_smaller_units(peak, factor, shown):
    """Tick labels stay short: an SED of 3.3e-5 MPa is shown as 33 Pa, not 0.000033."""
    from fingertip_dolfinx.plotting.fieldplots import value_text
    from fingertip_dolfinx.plotting.figures import display_unit

    assert display_unit("sed (MPa)", peak) == (factor, shown)
    assert display_unit("e_max (-)", 2.5e-6) == (1e6, "e_max (x 1e-6)")
    assert display_unit("e_max (-)", 0.05) == (1.0, "e_max (-)")  # 0.05 reads well as it is
    assert display_unit("u2 (mm)", 0.02) == (1e3, "u2 (µm)")
    assert display_unit("force (N/mm)", 1.2e-3) == (1e3, "force (mN/mm)")
    # a marked extreme in its own unit: a 20 kPa peak on a map whose colours stop at 55 Pa
    assert value_text("sed (MPa)", 0.0201) == "20.1 kPa"
    assert value_text("e_min (-)", -3.25e-4) == "-3.25e-04"


def test_the_force_history_names_a_half_models_force_and_draws_the_force_target(
        tmp_path, monkeypatch):
    """A half model's force is half the finger's: its axis says so; under force control the
    target (on the same footing, empty before force control starts) is drawn at the force's
    scale, so a held force lies on it."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.plotting.figures import plot_force_history

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    force = np.array([2e-4, 5e-4, 7.5e-4, 7.5e-4])
    history = {"time_s": np.array([0.1, 0.2, 0.3, 0.4]),
               "indenter_displacement_mm": np.array([0.1, 0.3, 0.5, 0.51]),
               "force_N": force, "normal_force_target_N": np.array([np.nan, np.nan, 7.5e-4,
                                                                    7.5e-4])}
    plot_force_history(history, tmp_path / "f.png", half=True)
    axis = drawn[-1].axes[1]
    assert axis.get_ylabel() == "force on the half model (mN)"
    measured, target = (line.get_ydata() for line in axis.get_lines())
    np.testing.assert_allclose(target[2:], measured[-2:])  # mN, both
    plot_force_history({k: v for k, v in history.items() if "target" not in k},
                       tmp_path / "g.png")
    assert drawn[-1].axes[1].get_ylabel() == "force (mN)"
    assert len(drawn[-1].axes[1].get_lines()) == 1


def test_the_3d_friction_figure_names_a_half_models_areas_and_forces(tmp_path, monkeypatch):
    """shear-3d and slide-3d are half models: history.csv's areas and forces are the half's
    own (the mirror image carries as much again), so the friction figure's axes say so, as
    the force history's do; a whole model's axes name the plain quantities."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.plotting.figures import plot_friction_3d

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    t = np.array([0.5, 1.0])
    history = {"time_s": t, "force_N": 0.4 * t, "tangential_x_force_N": 0.0 * t,
               "tangential_z_force_N": 0.1 * t, "contact_area_mm2": 2.0 * t,
               "stick_area_mm2": t}
    for half in (True, False):
        plot_friction_3d(history, tmp_path / "friction.png", 0.5, half=half)
        area, force = (" ".join(ax.get_ylabel().split()) for ax in drawn[-1].axes)
        assert area == ("area on the half model (mm², reference)" if half else
                        "area (mm², reference)")
        assert force == ("force on the half model (N)" if half else "force (N)")


def test_the_coulomb_panel_legend_covers_no_plotted_point(tmp_path, monkeypatch):
    """The forces panel of a sliding run, under its stick/slip map (slide-3d's shape: the
    press to 0.01 s, then the drag): the normal force flat at the top, the friction rising
    to μ times it, so the curves fill the panel's width; its legend must lie where no curve
    is drawn (it covered the friction's rise in slide-3d's figure)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from fingertip_dolfinx.plotting.figures import plot_friction_3d

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    t = np.linspace(0.0025, 0.035, 14)
    normal = 7.5e-4 * np.minimum(t / 0.01, 1.0)
    friction = np.interp(t, [0.0, 0.01, 0.0145, 0.035], [0.0, 4e-5, 3.8e-4, 3.75e-4])
    zero = 0.0 * t
    history = {"time_s": t, "pressure_normal_force_N": normal, "force_N": normal,
               "tangential_x_force_N": zero, "tangential_z_force_N": friction,
               "pressure_tangential_x_force_N": zero, "pressure_tangential_z_force_N": zero,
               "contact_area_mm2": 1.1 + zero, "stick_area_mm2": zero}
    z = np.linspace(5.0, 12.0, 8)
    stick_slip = {"x_mm": np.zeros(t.size * z.size), "z_mm": np.tile(z, t.size),
                  "time_s": np.repeat(t, z.size),
                  "contact_state": np.tile(np.where(abs(z - 8.5) < 1.0, 1, 0), t.size)}
    plot_friction_3d(history, tmp_path / "friction.png", 0.5, stick_slip=stick_slip,
                     half=True)
    fig = drawn[-1]
    FigureCanvasAgg(fig).draw()
    ax = fig.axes[-1]
    box = ax.get_legend().get_window_extent()
    for line in ax.get_lines():  # the lines between the points too, 50 samples a segment
        xy = line.get_xydata()
        s = np.linspace(0.0, len(xy) - 1.0, 50 * (len(xy) - 1) + 1)
        dense = np.column_stack([np.interp(s, np.arange(len(xy)), xy[:, i]) for i in (0, 1)])
        points = ax.transData.transform(dense)
        inside = ((points[:, 0] > box.x0) & (points[:, 0] < box.x1)
                  & (points[:, 1] > box.y0) & (points[:, 1] < box.y1))
        assert not inside.any(), f"{line.get_label()!r} drawn under the legend"


def test_the_spacing_figure_keeps_every_bar_and_its_peak_in_view(tmp_path, monkeypatch):
    """The profiles by spacing are shown over ±4 mm, enough for the spacings of the paper
    (up to 4 mm: bar centres at ±2 mm); a wider spacing (10 mm: bars at ±5 mm, within the
    profile's ±6 mm) widens the view, so its peaks under the bars are not cut off."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.plotting.figures import plot_spacing_profiles

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    x = np.linspace(-6.0, 6.0, 121)

    def run(d):  # a strain bump of 0.5 mm under each bar centre
        bump = np.exp(-((x - d / 2) / 0.5) ** 2) + np.exp(-((x + d / 2) / 0.5) ** 2)
        return {"x_mm": x, "depth_mm": np.ones_like(x), "time_s": np.ones_like(x),
                "e11": 1e-2 * bump, "e22": -1e-2 * bump, "e12": 5e-3 * bump,
                "sed_MPa": 1e-4 * bump}

    for spacings, edge in (((2.0, 4.0), 4.0), ((2.0, 10.0), 7.0)):
        plot_spacing_profiles({d: run(d) for d in spacings}, tmp_path / "p.png", 1.0, 1.0)
        for ax in drawn[-1].axes:
            assert ax.get_xlim() == pytest.approx((-edge, edge))
            for line in ax.get_lines()[::2]:  # the profiles (each followed by its bar ticks)
                peak = line.get_xdata()[np.argmax(np.abs(line.get_ydata()))]
                assert -edge < peak < edge


def _surface(title, path):
    from fingertip_dolfinx.plotting.figures import plot_surface_profiles

    x = np.linspace(-5.0, 5.0, 11)
    plot_surface_profiles({"x_mm": x, "time_s": np.ones(11), "deflection_mm": -np.exp(-x**2)},
                          path, title=f"{title}: across the finger")


def _population_3d(title, path):  # one class (an SA1-only population): the narrowest figure
    from fingertip_dolfinx.plotting.figures import plot_population_3d

    x = np.linspace(-6.0, 6.0, 9)
    plot_population_3d({"x_mm": x, "y_mm": -4.0 + 0 * x, "z_mm": 10.0 + x,
                        "mean_rate_per_s": 10.0 + x, "class": np.array(["SA1"] * 9)},
                       path, title)


def _impedance(title, path):
    from fingertip_dolfinx.frequency_response import plot_impedance

    plot_impedance([{"frequency_Hz": f, "K_abs_N_per_mm": 0.1 * f, "Z_abs_Ns_per_mm": 0.01,
                     "Z_phase_deg": -80.0} for f in (10.0, 100.0, 1000.0)], path, title, "N")


@pytest.mark.parametrize("draw", [_surface, _population_3d, _impedance])
def test_a_long_scene_title_stays_inside_the_figure(draw, tmp_path, monkeypatch):
    """A changed scene's title runs to 60 characters (`Scene.title`); what a figure adds to
    it (": across the finger", ": driving-point impedance", ": afferents seen from the
    palm") must not push it off the figure's edges: every title lies within the PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from fingertip_dolfinx.scene import TITLE_LENGTH

    drawn, save = [], Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (drawn.append(fig),
                                                                   save(fig, *a, **k)))
    title = "grating-3d — depth=0.8, mesh min_size=0.5, times=[0.5, 1, 2, 4]"
    title = title[:TITLE_LENGTH - 1] + "…"  # as Scene.title cuts it
    draw(title, tmp_path / "figure.png")
    fig = drawn[-1]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    texts = [ax.title for ax in fig.axes] + ([fig._suptitle] if fig._suptitle else [])
    shown = [t for t in texts if t.get_text()]
    assert shown
    for text in shown:
        box = text.get_window_extent(renderer)
        assert 0 <= box.x0 and box.x1 <= fig.bbox.width, (text.get_text(), box)



def test_the_3d_population_keeps_its_axis_labels_inside_the_figure(tmp_path):
    """The whole pulp seen from the palm (x ±7.5 mm across, z 0–21 mm along), three classes:
    at the figure's fixed 4.8 in height the equal-aspect panels pushed the x labels
    ("x (mm), across the finger") off the bottom of the PNG. The picture now ends in a white
    margin: no ink in its last rows."""
    from fingertip_dolfinx.plotting.figures import plot_population_3d

    rng = np.random.default_rng(0)
    n = 300
    classes = np.array(["SA1", "RA", "PC"])[rng.integers(0, 3, n)]
    path = tmp_path / "population.png"
    plot_population_3d({"x_mm": rng.uniform(-7.5, 7.5, n), "y_mm": np.full(n, -6.0),
                        "z_mm": rng.uniform(0.0, 21.0, n), "mean_rate_per_s": rng.uniform(0, 20, n),
                        "class": classes}, path, "probe-3d")
    grey = np.asarray(Image.open(path).convert("L"))
    inked = np.flatnonzero(grey.min(axis=1) < 128)
    assert inked.max() < grey.shape[0] - 5, (inked.max(), grey.shape)

@pytest.mark.parametrize("times", [3, 20])
def test_curves_of_many_output_times_keep_distinct_colours(times, tmp_path, monkeypatch):
    """One curve per output time: named in a legend while there are few; with many (a scene's
    `output.times` may list 20) the colour cycle's 10 colours would repeat, so two times would
    look alike and the legend outgrow the axes: a sequential colour map and a colour bar of
    the time instead."""
    from matplotlib.colors import to_rgba
    from matplotlib.figure import Figure

    from fingertip_dolfinx.plotting.figures import plot_line_force, plot_surface_profiles

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    x, t = np.linspace(-6.0, 6.0, 13), np.linspace(0.1, 2.0, times)
    columns = {"time_s": np.repeat(t, 13), "x_mm": np.tile(x, times), "z_mm": np.tile(x, times)}
    bump = np.concatenate([s * np.exp(-x**2) for s in t])
    plot_surface_profiles({**columns, "deflection_mm": -bump}, tmp_path / "s.png")
    plot_line_force({**columns, "force_per_length_N_per_mm": bump}, tmp_path / "f.png")
    for fig in drawn:
        colours = {to_rgba(line.get_color()) for line in fig.axes[0].get_lines()}
        assert len(colours) == times
        assert (fig.axes[0].get_legend() is not None) == (times <= 8)
        assert len(fig.axes) == (1 if times <= 8 else 2)  # the colour bar of the time


def test_a_title_draws_square_brackets_as_brackets():
    """A changed scene's title quotes its overrides ("indenters=[cylinder r=5]"); VTK's own
    "arial" drew "[" as "(", so the picture named another value than the one given. In the
    pictures' font (fieldplots._text) a "[" starts with its horizontal stub: its top rows of
    ink are at least twice as wide as a "("'s (measured: 16 px against 7; VTK's arial: 4, 4)."""
    import pyvista as pv

    from fingertip_dolfinx.plotting.fieldplots import _text

    def top_width(glyph):
        plotter = pv.Plotter(off_screen=True, window_size=[120, 120])
        plotter.set_background("white")
        _text(plotter, glyph, position=(20, 20), font_size=40, color="black")
        ink = np.asarray(plotter.screenshot(return_img=True), dtype=float).mean(-1) < 128
        plotter.close()
        first = np.flatnonzero(ink.any(1))[0]
        return int(ink[first:first + 2].any(0).sum())  # the glyph's top two rows of ink

    assert top_width("[") >= 2 * top_width("(")


@pytest.mark.parametrize("extremes", [1, 2])
def test_the_colour_bar_caption_fits_the_picture(extremes):
    """The caption names the label and each extreme beyond the bar with its place; with both
    ends saturated it is ~130 characters, which must stay inside the picture's width."""
    import pyvista as pv

    from fingertip_dolfinx.plotting.fieldplots import _text, caption_size

    notes = ["max 7.34 kPa at (-0.02, -6.00) mm", "min -12.3 kPa at (-10.25, -16.50) mm"]
    caption = ("strain energy density (Pa); colours saturate beyond the bar: "
               + ", ".join(notes[:extremes]))
    plotter = pv.Plotter(off_screen=True, window_size=list(WINDOW_SIZE))
    plotter.set_background("white")
    text = _text(plotter, caption, position=(0.52, 0.08), viewport=True,
                 font_size=caption_size(caption), color="black")
    text.GetTextProperty().SetJustificationToCentered()
    ink = np.asarray(plotter.screenshot(return_img=True), dtype=float).mean(-1) < 128
    plotter.close()
    columns = np.flatnonzero(ink.any(0))
    assert columns[0] > 5 and columns[-1] < WINDOW_SIZE[0] - 5, (columns[0], columns[-1])


def test_the_sweep_figure_shows_small_values_in_smaller_units(tmp_path, monkeypatch):
    """sweep.png states forces below 0.1 N/mm in mN/mm and an SED below 0.1 MPa in kPa, as the
    runs' own figures do (docs/guide/figures.md), with the values scaled to match; before, its
    panels read N/mm and MPa with a x10^-3 offset above the axis."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.keys import KEY_OUTPUTS
    from fingertip_dolfinx.studies.parameters import _plot

    drawn, save = [], Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (drawn.append(fig),
                                                                   save(fig, *a, **k)))
    rows = []
    for i, k0 in enumerate((1e-3, 1.0)):
        (tmp_path / f"k0={k0:g}").mkdir()
        (tmp_path / f"k0={k0:g}" / "history.csv").write_text(
            f"time_s,force_N_per_mm\n0.5,0.7e-3\n1.0,{1.44e-3 - 1e-5 * i}\n")
        row = {"label": f"k0={k0:g}", "value": k0}
        for key in KEY_OUTPUTS:
            row[key.column] = {"force": 1.44e-3, "sed": 2.2e-4}.get(key.quantity, 0.5) - 1e-6 * i
            row[f"{key.column}_t_s"] = 1.0
        rows.append(row)
    _plot(tmp_path, {"scene": "1pt", "key": "materials.subcutaneous.permeability.k0",
                     "factors": [], "rows": rows})
    axes = drawn[-1].axes
    assert axes[0].get_ylabel() == "force (mN/mm)"
    assert max(line.get_ydata().max() for line in axes[0].lines) == pytest.approx(1.44)
    titles = {ax.get_title().split("\n")[0] for ax in axes[1:8]}
    assert {"force (mN/mm)", "SED (kPa)", "deflection (mm)"} <= titles, titles
    sed = next(ax for ax in axes[1:8] if ax.get_title().startswith("SED"))
    assert sed.collections[0].get_offsets()[:, 1].max() == pytest.approx(0.22)


def test_a_sweep_panel_shows_values_that_differ_in_their_sixth_digit_as_they_are():
    """The permeability sweep's forces, 1.439380e-3 to 1.439374e-3 N/mm: the panel's axis read
    "×10⁻⁹ + 1.4393×10⁻³" above ticks 74–80 (an offset), which reads as another number. The
    ticks now carry the values themselves (×10⁻³ above them, no offset)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from fingertip_dolfinx.studies.parameters import _sci

    fig = Figure()
    ax = fig.subplots()
    ax.plot([0.1, 1.0, 10.0], [1.43938046e-3, 1.43937985e-3, 1.43937377e-3])
    _sci(ax)
    FigureCanvasAgg(fig).draw()
    offset = ax.yaxis.get_offset_text().get_text().replace("\N{MINUS SIGN}", "-")
    assert "+" not in offset and "10^{-3}" in offset, offset
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert labels and all("{1.4393" in label for label in labels), labels
