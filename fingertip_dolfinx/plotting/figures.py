"""Figures drawn with matplotlib (no display): the tagged mesh, and the result curves (force,
surface deflection, depth profiles); small values shown in a smaller unit (`display_unit`)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib
import numpy as np
from dolfinx.mesh import CellType, entities_to_geometry
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure  # no pyplot: no backend is chosen, none is changed
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ..geometry.mesh import CELL_TAGS, FACET_TAGS, FingertipMesh

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
    fig = Figure(figsize=(12.5, 5.4))
    axes = fig.subplots(1, 2, width_ratios=[1.15, 1])
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
    return path


# --------------------------------------------------------------------------------------------
# Units a reader can read: small values in a smaller unit (33 Pa, not 0.000033 MPa).

#: Units shown in a smaller one when the values are small: (factor, name), largest first; a
#: unit is used down to a tenth of it (0.25 MPa, 0.8 kPa, 33 Pa; 0.5 mm, 40 µm).
SMALLER_UNITS = {"MPa": ((1.0, "MPa"), (1e3, "kPa"), (1e6, "Pa")),
                 "mm": ((1.0, "mm"), (1e3, "µm")),
                 "N/mm": ((1.0, "N/mm"), (1e3, "mN/mm")),
                 "N": ((1.0, "N"), (1e3, "mN"))}


def unit_of(label: str) -> str:
    """The unit in a label's last parentheses ("sed (MPa)" -> "MPa"), "" if none."""
    if not label.endswith(")") or "(" not in label:
        return ""
    return label[label.rindex("(") + 1:-1]


def display_unit(label: str, peak: float) -> tuple[float, str]:
    """(factor, label) to show values up to `peak` (in the label's unit) with short ticks: the
    unit of SMALLER_UNITS that puts `peak` at 0.1 or more; for other units, below 0.01, a
    power of 1000 written in the label ("e_max (x 1e-3)")."""
    unit = unit_of(label)
    named = SMALLER_UNITS.get(unit)
    if not np.isfinite(peak) or peak == 0 or peak >= (0.1 if named else 0.01):
        return 1.0, label
    stem = label[: len(label) - len(unit) - 2].rstrip()
    if named:
        factor, name = next((u for u in named if u[0] * peak >= 0.1), named[-1])
        return factor, f"{stem} ({name})"
    power = 3 * int(np.floor(np.log10(10 * peak) / 3))  # 3e-5 -> 1e-6: ticks up to 30
    dimension = "" if unit in ("", "-") else f" {unit}"
    return 10.0**-power, f"{stem} (x 1e{power}{dimension})"


def plain_log_ticks(ax, which: str = "x") -> None:
    """Tick labels of a log axis as plain numbers (40, 50, 1000, not 4×10¹); when it spans under
    1.5 decades, where few powers of ten fall, the minor ticks are labelled too. Call after
    plotting (the span is the axis's view)."""
    from matplotlib.ticker import FuncFormatter

    low, high = ax.get_xlim() if which == "x" else ax.get_ylim()
    axis = ax.xaxis if which == "x" else ax.yaxis
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    axis.set_major_formatter(plain)
    axis.set_minor_formatter(plain if high / low < 30 else FuncFormatter(lambda v, _: ""))


def fitted(text: str, fig, fontsize: float = 12.0) -> str:
    """`text` broken at spaces into lines that fit the figure's width at `fontsize` points:
    a scene's title (`Scene.title`, up to 60 characters with the overrides) and what a figure
    adds to it must not run off the figure's edges. A character is taken as 0.6 em, wider
    than DejaVu Sans's average (about 0.55 em), so a line errs on the short side."""
    chars = int(0.95 * fig.get_figwidth() * 72.0 / (0.6 * fontsize))
    return text if len(text) <= chars else "\n".join(textwrap.wrap(text, chars))


def _scaled(values, label: str) -> tuple[np.ndarray, str]:
    """`values` in the unit display_unit chooses for them, and its label."""
    values = np.asarray(values, dtype=float)
    factor, label = display_unit(label, float(np.nanmax(np.abs(values), initial=0.0)))
    return factor * values, label


# --------------------------------------------------------------------------------------------
# Result figures, from the result files' columns (numpy arrays) on rank 0.


def plot_force_history(history: dict, path: Path, title: str = "", half: bool = False) -> None:
    """Indenter displacement and force per unit length against time (cf. the paper's Fig. 3);
    `half`: the forces are a half model's (its mirror image carries as much again). Under force
    control, the target (history's, on the same footing) dashed."""
    fig = Figure(figsize=(6.4, 6.0))
    (ax_d, ax_f) = fig.subplots(2, 1, sharex=True)
    t = np.concatenate([[0.0], history["time_s"]])
    ax_d.plot(t, np.concatenate([[0.0], history["indenter_displacement_mm"]]), "k-")
    ax_d.set_ylabel("indentation (mm)")
    column, unit = force_column(history)
    name = "force on the half model" if half else "force"
    force = np.concatenate([[0.0], history[column]])
    factor, label = display_unit(f"{name} ({unit})", float(np.nanmax(np.abs(force), initial=0)))
    ax_f.plot(t, factor * force, "o-", ms=3)
    target = next((history[k] for k in ("normal_force_target_N_per_mm", "normal_force_target_N")
                   if k in history), None)
    if target is not None:  # empty (NaN) before force control starts: not drawn there
        ax_f.plot(history["time_s"], factor * target, "k--", lw=1, label="force control's target")
        ax_f.legend(fontsize=8, loc="lower right")
    ax_f.set_ylabel(label)
    ax_f.set_xlabel("time (s)")
    if t[-1] > 10:
        for ax in (ax_d, ax_f):
            ax.set_xscale("symlog", linthresh=1.0)
    ax_d.set_title(title)
    for ax in (ax_d, ax_f):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def force_column(history: dict) -> tuple[str, str]:
    """The force column of a history and its unit: N/mm in plane strain, N in 3D."""
    return ("force_N", "N") if "force_N" in history else ("force_N_per_mm", "N/mm")


#: The stick/slip map's colours, by `outputs.CONTACT_STATES` code: free, slip, stick.
STATE_COLOURS = ("#f2f2f2", "#f28e2b", "#4e79a7")


def plot_friction(stick_slip: dict, history: dict, path: Path, mu: float,
                  title: str = "") -> None:
    """Above: each surface point's state (free, slip, stick) at each step, its reference x
    against time (a step's state fills the interval that ends at it). Below: the normal
    force, the tangential force and Coulomb's bound μ times the normal force, against time."""
    fig = Figure(figsize=(6.4, 6.4))
    ax_m, ax_f = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    _state_map(ax_m, stick_slip, "x_mm", "surface point x (mm, reference)")
    ax_m.set_title(title)
    t = np.concatenate([[0.0], history["time_s"]])
    column, unit = force_column(history)
    normal = np.abs(np.concatenate([[0.0], history[column]]))
    tangential = np.abs(np.concatenate([[0.0], history[f"tangential_{column}"]]))
    _coulomb_panel(ax_f, t, normal, tangential, mu, f"force ({unit})", "tangential force")
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def stick_slip_grid(stick_slip: dict, key: str, times=None) -> tuple:
    """stick_slip.csv's states as a grid for pcolormesh: the surface points' reference
    coordinate `key` (sorted), its cell edges (midpoints, the ends at the end points) and
    the state (0 free, 1 slip, 2 stick; NaN where a point has no row) of each point at each
    of `times` (default: every step's), one column a time."""
    times = np.unique(stick_slip["time_s"]) if times is None else np.asarray(times)
    x = np.unique(stick_slip[key])
    state = np.full((len(x), len(times)), np.nan)
    for j, t in enumerate(times):
        rows = np.isclose(stick_slip["time_s"], t, rtol=0, atol=1e-12)
        state[np.searchsorted(x, stick_slip[key][rows]), j] = stick_slip["contact_state"][rows]
    return x, np.concatenate([[x[0]], 0.5 * (x[1:] + x[:-1]), [x[-1]]]), state


def _state_map(ax, stick_slip: dict, key: str, label: str) -> None:
    """Each surface point's state (free, slip, stick) at each step: its reference coordinate
    `key` against time (a step's state fills the interval that ends at it)."""
    _, x_edges, state = stick_slip_grid(stick_slip, key)
    t_edges = np.concatenate([[0.0], np.unique(stick_slip["time_s"])])
    colours = matplotlib.colors.ListedColormap(STATE_COLOURS)
    ax.pcolormesh(t_edges, x_edges, state, cmap=colours, vmin=-0.5, vmax=2.5)
    ax.legend(handles=[Patch(color=c, label=n) for c, n in
                       zip(STATE_COLOURS, ("free", "slip", "stick"))],
              loc="upper left", fontsize=8)
    ax.set_ylabel(label)


#: The force panels' upper limit over their largest value: room above the curves for the
#: three-line legend.
LEGEND_HEADROOM = 1.7


def _coulomb_panel(ax, t, normal, tangential, mu: float, quantity: str, name: str,
                   normal_name: str = "normal force") -> None:
    """The normal and tangential forces against time with Coulomb's bound μ × normal."""
    factor, label = display_unit(quantity, float(np.max(normal)))
    ax.plot(t, factor * normal, "k-", label=normal_name)
    ax.plot(t, factor * tangential, "o-", ms=3, color=STATE_COLOURS[1], label=name)
    ax.plot(t, factor * mu * normal, "--", color="0.4", label=f"μ × {normal_name} (μ = {mu:g})")
    ax.set_ylabel(label)
    ax.set_xlabel("time (s)")
    # The three curves fill the panel once the friction saturates at the bound: headroom
    # above the normal force keeps the legend off them.
    ax.set_ylim(top=LEGEND_HEADROOM * factor * float(np.max(normal)))
    ax.legend(fontsize=8, loc="upper left", ncols=1)
    ax.grid(alpha=0.3)


def plot_friction_3d(history: dict, path: Path, mu: float, title: str = "",
                     stick_slip: dict | None = None, half: bool = False) -> None:
    """A 3D run with friction, from history.csv (and stick_slip.csv). At the top, given
    `stick_slip`: the stick/slip map along the finger (z against time, on the line of
    surface_along.csv). Then the contact area and its sticking part against time; below, the
    pressure's normal force, the friction's tangential share and Coulomb's bound μ times the
    former (`_coulomb_forces_3d`). `half`: the areas and forces are a half model's (history.csv
    holds the half's own; its mirror image carries as much again), and the labels say so."""
    if stick_slip is None:
        fig = Figure(figsize=(6.4, 6.4))
        ax_a, ax_f = fig.subplots(2, 1, sharex=True, height_ratios=(1, 1))
    else:
        fig = Figure(figsize=(6.4, 8.8))
        ax_m, ax_a, ax_f = fig.subplots(3, 1, sharex=True, height_ratios=(3, 2, 2))
        x = np.unique(stick_slip["x_mm"])
        _state_map(ax_m, stick_slip, "z_mm", f"surface point z (mm, reference; x = {x[0]:g})")
        touched = stick_slip["z_mm"][stick_slip["contact_state"] > 0]
        if len(touched):  # the contact's strip and 2 mm either side, not the whole finger
            ax_m.set_ylim(max(touched.min() - 2.0, 0.0),
                          min(touched.max() + 2.0, stick_slip["z_mm"].max()))
        ax_m.set_title(title)
        title = ""
    t = np.concatenate([[0.0], history["time_s"]])
    for key, colour, label in (("contact_area_mm2", "0.3", "in contact"),
                               ("stick_area_mm2", STATE_COLOURS[2], "sticking")):
        ax_a.plot(t, np.concatenate([[0.0], history[key]]), "o-", ms=3, color=colour,
                  label=label)
    # a half model's labels on two lines: the panels are too short for one
    ax_a.set_ylabel("area on the half model\n(mm², reference)" if half
                    else "area (mm², reference)")
    ax_a.legend(fontsize=8)
    ax_a.grid(alpha=0.3)
    ax_a.set_title(title)
    _coulomb_panel(ax_f, t, *_coulomb_forces_3d(history), mu,
                   "force on the\nhalf model (N)" if half else "force (N)",
                   "friction's tangential share |(F_x − F_p,x, F_z − F_p,z)|"
                   if "pressure_normal_force_N" in history else "tangential force |(F_x, F_z)|",
                   "pressure's normal force F_p,y" if "pressure_normal_force_N" in history
                   else "normal force")
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def _coulomb_forces_3d(history: dict) -> tuple[np.ndarray, np.ndarray]:
    """(normal, tangential) from a 3D history, from t = 0: with the pressure's shares
    (`pressure_normal_force_N`), the pressure's normal force and the friction traction's
    tangential share, whose bound μ F_p,y holds on a curved indenter too (to the contact's
    tilt; a half model's pressure has an x-share, the mirror's); else the total forces."""
    if "pressure_normal_force_N" not in history:  # a run before that column
        normal, tangential = history["force_N"], np.hypot(history["tangential_x_force_N"],
                                                          history["tangential_z_force_N"])
    else:
        normal = history["pressure_normal_force_N"]
        tangential = np.hypot(
            history["tangential_x_force_N"] - history["pressure_tangential_x_force_N"],
            history["tangential_z_force_N"] - history["pressure_tangential_z_force_N"])
    return (np.abs(np.concatenate([[0.0], normal])), np.concatenate([[0.0], tangential]))


#: Up to this many output times, one curve each in the colour cycle, named in a legend.
LEGEND_TIMES = 8


def _time_colours(fig, ax, times) -> list:
    """The colour of each output time's curve: the colour cycle's (and a legend, drawn by the
    caller) up to LEGEND_TIMES; beyond, where the cycle's 10 colours would repeat and the
    legend outgrow the axes, a sequential colour map and a colour bar of the time."""
    if len(times) <= LEGEND_TIMES:
        return [f"C{i}" for i in range(len(times))]
    norm, cmap = Normalize(float(times[0]), float(times[-1])), matplotlib.colormaps["viridis"]
    fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="output time (s)")
    return [cmap(norm(t)) for t in times]


def plot_surface_profiles(profile: dict, path: Path, title: str = "", along: str = "x") -> None:
    """Deflection of the pulp surface along x (or z: `along`) at each output time (cf. the
    paper's Fig. 2)."""
    fig = Figure(figsize=(6.4, 4.0))
    ax = fig.subplots()
    key = f"{along}_mm"
    times = np.unique(profile["time_s"])
    for t, colour in zip(times, _time_colours(fig, ax, times)):
        rows = profile["time_s"] == t
        order = np.argsort(profile[key][rows])
        ax.plot(profile[key][rows][order], profile["deflection_mm"][rows][order],
                color=colour, label=f"t = {t:g} s")
    ax.set_xlabel("x (mm), distance from the load axis" if along == "x" else
                  "z (mm), along the finger from the proximal cut")
    ax.set_ylabel("surface deflection (mm)")
    ax.set_title(fitted(title, fig))
    ax.grid(alpha=0.3)
    if len(times) <= LEGEND_TIMES:
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def plot_line_force(line: dict, path: Path, title: str = "") -> None:
    """A 3D run's y-force per unit length of finger f(z) at each output time: what a
    plane-strain section carries where the finger is long and straight."""
    fig = Figure(figsize=(6.4, 4.0))
    ax = fig.subplots()
    factor, label = display_unit("force per unit length (N/mm)", float(
        np.nanmax(np.abs(line["force_per_length_N_per_mm"]), initial=0.0)))
    times = np.unique(line["time_s"])
    for t, colour in zip(times, _time_colours(fig, ax, times)):
        rows = line["time_s"] == t
        ax.step(line["z_mm"][rows], factor * line["force_per_length_N_per_mm"][rows],
                where="mid", color=colour, label=f"t = {t:g} s")
    ax.set_xlabel("z (mm), along the finger from the proximal cut")
    ax.set_ylabel(label)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if len(times) <= LEGEND_TIMES:
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=150)


DEPTH_QUANTITIES = (("e_max", "max principal log strain (-)"),
                    ("e_min", "min principal log strain (-)"),
                    ("e12", "shear log strain e12 (-)"), ("sed_MPa", "strain energy density (MPa)"))


def plot_depth_profiles(depth: dict, path: Path, time_s: float, title: str = "") -> None:
    """Strains and SED along the curves at fixed depths (cf. the paper's Fig. 5)."""
    fig = Figure(figsize=(9.6, 6.4))
    axes = fig.subplots(2, 2, sharex=True)
    at_time = np.isclose(depth["time_s"], time_s)
    for ax, (key, label) in zip(axes.ravel(), DEPTH_QUANTITIES):
        values, label = _scaled(depth[key][at_time], label)
        for d in np.unique(depth["depth_mm"][at_time]):
            rows = depth["depth_mm"][at_time] == d
            ax.plot(depth["x_mm"][at_time][rows], values[rows], label=f"depth {d:g} mm")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("x (mm)")
    axes[0, 0].legend()
    fig.suptitle(f"{title} (t = {time_s:g} s)")
    fig.tight_layout()
    fig.savefig(path, dpi=150)


#: The paper's Figs 7-8: strains in x/y, shear strain and SED at one depth, per bar spacing.
SPACING_QUANTITIES = (("e11", "horizontal log strain e11 (-)"),
                      ("e22", "vertical log strain e22 (-)"),
                      ("e12", "shear log strain e12 (-)"),
                      ("sed_MPa", "strain energy density (MPa)"))


def plot_spacing_profiles(runs: dict[float, dict], path: Path, time_s: float, depth_mm: float,
                          title: str = "") -> None:
    """One curve per bar spacing d (`runs[d]` = that run's depth_profiles.csv columns) at the
    depth `depth_mm` and time `time_s`; the bar centres ±d/2 are marked (cf. Figs 7-8)."""
    fig = Figure(figsize=(9.6, 6.4))
    axes = fig.subplots(2, 2, sharex=True)
    colours = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.9, len(runs)))
    at = {d: np.isclose(r["time_s"], time_s) & np.isclose(r["depth_mm"], depth_mm)
          for d, r in runs.items()}
    for ax, (key, label) in zip(axes.ravel(), SPACING_QUANTITIES):
        peak = max(float(np.nanmax(np.abs(r[key][at[d]]), initial=0.0)) for d, r in runs.items())
        factor, label = display_unit(label, peak)
        for colour, (d, depth) in zip(colours, sorted(runs.items(), reverse=True)):
            order = np.argsort(depth["x_mm"][at[d]])
            ax.plot(depth["x_mm"][at[d]][order], factor * depth[key][at[d]][order],
                    color=colour, label=f"d = {d:g} mm")
            ax.plot([-d / 2, d / 2], [0.0, 0.0], "|", color=colour, ms=8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    # ±4 mm around the load axis, wider for a spacing that puts a bar centre within 2 mm of
    # that edge: each bar and its flank stay in view (no peak cut off by the axis)
    edge = max(4.0, max(runs) / 2 + 2.0)
    for ax in axes[1]:
        ax.set_xlabel("x (mm); ticks on the axis: bar centres")
        ax.set_xlim(-edge, edge)
    handles, labels = axes[0, 0].get_legend_handles_labels()  # beside the panels: off the data
    fig.legend(handles, labels, loc="center right", fontsize=8)
    fig.suptitle(f"{title} at depth {depth_mm:g} mm, t = {time_s:g} s")
    fig.tight_layout(rect=(0, 0, 0.88, 1))
    fig.savefig(path, dpi=150)


#: The population picture's marker of each afferent class.
CLASS_MARKERS = {"SA1": "o", "RA": "s", "PC": "D"}


def plot_population(afferents: dict, outer, path: Path, title: str = "") -> None:
    """The afferents of a run at their sites on the section (reference positions), coloured
    by their mean firing rate over the run, one marker per class, with the palmar outer
    surface for orientation (afferents.csv's columns; `outer`: the section's outer ellipse)."""
    if "z_mm" in afferents:
        return plot_population_3d(afferents, path, title)
    fig = Figure(figsize=(8.0, 4.2))
    ax = fig.subplots()
    x, y, rate = afferents["x_mm"], afferents["y_mm"], afferents["mean_rate_per_s"]
    half = float(np.max(np.abs(x))) + 1.0
    edge = min(half / outer.a, 1.0)  # the palmar arc: x = a cos u, u in (−π, 0)
    u = np.linspace(-np.arccos(-edge), -np.arccos(edge), 200)
    surface = outer.point(u)
    ax.plot(surface[:, 0], surface[:, 1], color="0.3", lw=1.0, label="outer surface")
    norm = Normalize(0.0, max(float(np.max(rate, initial=0.0)), 1.0))
    for name, marker in CLASS_MARKERS.items():
        rows = afferents["class"] == name
        if rows.any():
            points = ax.scatter(x[rows], y[rows], c=rate[rows], cmap="viridis", norm=norm,
                                marker=marker, s=36, edgecolors="k", linewidths=0.5,
                                label=f"{name} ({rows.sum()})")
    fig.colorbar(points, ax=ax, label="mean rate over the run (spikes/s)", shrink=0.7)
    ax.set_ylim(min(float(surface[:, 1].min()), float(y.min())) - 0.4, float(y.max()) + 0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=4, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def plot_population_3d(afferents: dict, path: Path, title: str = "") -> None:
    """A 3D run's afferents seen from the palm (their sites projected on the x–z plane: across
    and along the finger), one panel per class, coloured by mean firing rate over the run
    (one colour scale); afferents.csv's columns."""
    names = [n for n in CLASS_MARKERS if np.any(afferents["class"] == n)]
    # Panels of equal aspect, 3.2 in wide: the figure as tall as the pulp's extent along the
    # finger makes them, plus the titles and the axis label (at a fixed 4.8 in, the layout
    # gave the panels more height than the aspect lets them use and the x label fell off
    # the bottom).
    extent = np.ptp(afferents["z_mm"]) / max(float(np.ptp(afferents["x_mm"])), 1e-9)
    fig = Figure(figsize=(3.2 * len(names) + 1.2, 2.9 * min(max(extent, 0.5), 3.0) + 1.6),
                 layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(names), sharex=True, sharey=True))
    rate = afferents["mean_rate_per_s"]
    norm = Normalize(0.0, max(float(np.max(rate, initial=0.0)), 1.0))
    for ax, name in zip(axes, names):
        rows = afferents["class"] == name
        order = np.argsort(rate[rows])  # the firing ones on top
        points = ax.scatter(afferents["x_mm"][rows][order], afferents["z_mm"][rows][order],
                            c=rate[rows][order], cmap="viridis", norm=norm,
                            s=np.where(rate[rows][order] > 0, 24, 10),
                            marker=CLASS_MARKERS[name], edgecolors="none")
        ax.set_title(f"{name}: {rows.sum()} afferents, {int(np.sum(rate[rows] > 0))} firing",
                     fontsize=9)
        ax.set_xlabel("x (mm), across the finger")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("z (mm), along the finger (tip at the top)")
    fig.colorbar(points, ax=list(axes), label="mean rate over the run (spikes/s)", shrink=0.8)
    fig.suptitle(fitted(f"{title}: afferents seen from the palm", fig, 10), fontsize=10)
    fig.savefig(path, dpi=150)
