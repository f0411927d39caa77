"""The results of a run as arrays: what `ft.run` returns and `load_result(DIR)` reads back.

A `Result` reads a time run's own files (summary.json, history.csv, surface_profile.csv,
depth_profiles.csv, fields_t<t>s.npz), so a finished, failed or resumed run, or one made on
another machine, is read the same way; nothing needs CSV parsing by hand. A
`FrequencyResult` reads the frequency route's (frequency_response.csv, receptor_transfer.csv,
thresholds.csv, receptors.csv, summary.json).
"""

from __future__ import annotations

import csv
import json
import math
from functools import cached_property
from pathlib import Path

import numpy as np

from .errors import InputError
from .outputs import read_csv


class Result:
    """A run's results in `out`.

    - `summary`: summary.json as a dict (scene, materials, model, mesh, dofs, steps, ...);
    - `history`: per accepted step, columns as arrays (`time_s`, `force_N_per_mm`, ...);
    - `surface`, `depth`: the profiles at the output times, columns as arrays;
    - `fields(t)`: the fields at output time t as arrays (see `post.FieldArrays`);
    - `receptors()`: the receptor sites' samples per step (receptors.csv), if the run wrote them;
    - `spikes`, `afferents`, `rates`: every afferent's spikes, its site and model, its rate
      history (spikes.csv, afferents.csv, rates.npz), if the run had receptors;
    - shortcuts `time`, `force`, `surface_profile(t)`, `depth_profile(quantity, depth, t)`;
    - `route`: "time" or "adaptive" when `ft.run` returned it (None when read back).
    """

    route: str | None = None

    def __init__(self, out: str | Path):
        self.out = Path(out)
        if not (self.out / "history.csv").exists():
            raise InputError(str(self.out), "holds no run (no history.csv).",
                             "give the --out directory of a run.")

    def __repr__(self) -> str:
        s = self.summary
        unit = self.force_unit
        return (f"Result({str(self.out)!r}: {s.get('scene')}, {s.get('time_steps')} steps, "
                f"peak force {s.get('peak_force_' + unit.replace('/', '_per_'))} {unit}, "
                f"converged {s.get('converged')})")

    @cached_property
    def summary(self) -> dict:
        return json.loads((self.out / "summary.json").read_text())

    @cached_property
    def history(self) -> dict[str, np.ndarray]:
        return read_csv(self.out / "history.csv")

    @cached_property
    def surface(self) -> dict[str, np.ndarray]:
        return _read_if_there(self.out / "surface_profile.csv")

    @cached_property
    def depth(self) -> dict[str, np.ndarray]:
        return _read_if_there(self.out / "depth_profiles.csv")

    @property
    def time(self) -> np.ndarray:
        return self.history["time_s"]

    @property
    def force_unit(self) -> str:
        """'N/mm' for a plane-strain run (per unit thickness), 'N' for a 3D run."""
        return "N" if "force_N" in self.history else "N/mm"

    @property
    def force(self) -> np.ndarray:
        """Indenter force at every accepted step, in `force_unit`: per unit thickness (N/mm)
        in 2D; in N in 3D, where a half model's force is its own half (the whole finger's is
        `summary["mirror_factor"]` times it)."""
        return self.history["force_" + self.force_unit.replace("/", "_per_")]

    @property
    def output_times(self) -> list[float]:
        return sorted(float(t) for t in np.unique(self.depth.get("time_s", [])))

    def surface_profile(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(x, deflection) of the pulp surface at output time t (mm)."""
        rows = np.isclose(self.surface["time_s"], t)
        return self.surface["x_mm"][rows], self.surface["deflection_mm"][rows]

    def depth_profile(self, quantity: str, depth: float, t: float) -> tuple[np.ndarray, ...]:
        """(x, values) of a depth_profiles.csv column (`e11`, `sed_MPa`, ...) along the curve
        `depth` mm below the surface at output time t."""
        if quantity not in self.depth:
            raise InputError(f"quantity {quantity!r}", "is not a column of depth_profiles.csv.",
                             f"use one of {', '.join(self.depth)}.")
        at_depth = np.isclose(self.depth["depth_mm"], depth)
        if not at_depth.any():
            written = sorted(float(d) for d in np.unique(self.depth["depth_mm"]))
            raise InputError(f"depth {depth} mm", "was not written by this run.",
                             f"use a written depth, {written} mm (or run again with "
                             f"output.depths = [{depth}]).")
        rows = at_depth & np.isclose(self.depth["time_s"], t)
        if not rows.any():
            raise InputError(f"t = {t} s", "was not an output time of this run.",
                             f"use an output time, {self.output_times} s.")
        return self.depth["x_mm"][rows], self.depth[quantity][rows]

    def receptors(self) -> dict[str, np.ndarray]:
        """receptors.csv (a run with `output.receptors`) as columns: `time_s`, `class`
        (strings), `index` (integers), `x_mm`, `depth_mm`, `sed_MPa`, `e_min`, `sigma22_MPa`,
        `p_MPa`; one row per receptor per accepted step. Rates and spikes:
        `receptors.afferent_responses(result)`."""
        path = self.out / "receptors.csv"
        if not path.exists():
            raise InputError(str(self.out), "holds no receptors.csv.",
                             'run the scene with output.receptors = "default" (or a set).')
        return _read_table(path, text=("class",), integer=("index",))

    @cached_property
    def spikes(self) -> dict[str, np.ndarray]:
        """spikes.csv (a run with `output.receptors`): one row per spike, `class` (strings),
        `afferent`, `site` (integers), `time_s`."""
        return _read_table(self._receptor_file("spikes.csv"), ("class",), ("afferent", "site"))

    @cached_property
    def afferents(self) -> dict[str, np.ndarray]:
        """afferents.csv: one row per afferent, `class`, `model` (strings), `afferent`, `site`,
        `fit` (−1: a model without fits), `spikes` (integers), its site's reference position
        `x_mm`, `y_mm` (3D: `z_mm`), `depth_mm`, `mean_rate_per_s`."""
        return _read_table(self._receptor_file("afferents.csv"), ("class", "model"),
                           ("afferent", "site", "fit", "spikes"))

    @cached_property
    def rates(self) -> dict[str, np.ndarray]:
        """rates.npz, the firing-rate histories: `edges_s` (the time bins' edges), `counts`
        and `rate_per_s` (bins × afferents; column j is afferent `afferent[j]`), `class`,
        `site`."""
        with np.load(self._receptor_file("rates.npz")) as data:
            return {k: data[k] for k in data.files}

    def _receptor_file(self, name: str) -> Path:
        path = self.out / name
        if not path.exists():
            raise InputError(str(self.out), f"holds no {name} (a run with output.receptors "
                             "writes it when it ends).", 'run the scene with output.receptors '
                             '= "calibrated" (or another set).')
        return path

    def fields(self, t: float) -> dict[str, np.ndarray]:
        """The fields at output time t, cell by cell (see `post.FieldArrays`): the corners'
        reference coordinates `X` and displacement `u` (cells, corners, gdim; mm), the cell's
        `region` tag, at the corners `sed` (MPa), `log_strain` (gdim² components) and
        `principal` (the principal log strains, largest first); with a pore pressure, the
        subcutaneous cells' corners `X_p`, `u_p` and `p` (MPa)."""
        path = self._fields_path(t)
        with np.load(path) as data:
            return {k: data[k] for k in data.files}

    def _fields_path(self, t: float) -> Path:
        """fields_t<t>s.npz of the output time t; InputError if t is not one or the run
        stored no field arrays."""
        times = self.output_times
        at = [s for s in times if math.isclose(s, t, rel_tol=1e-9, abs_tol=1e-12)]
        if not at:
            raise InputError(f"t = {t:g} s", "is not an output time of this run.",
                             f"use one of its output times, {times} s (or run again with "
                             f"output.times including {t:g}).")
        path = self.out / f"fields_t{at[0]:g}s.npz"
        if not path.exists():
            raise InputError(f"fields at t = {t:g} s", f"this run stored no field arrays "
                             f"({path.name} is missing).", "open its fields (*.bp, mesh.xdmf) "
                             "in ParaView, or run the scene again to write them.")
        return path

    def to_pyvista(self, t: float, warp: bool | float = False):
        """The fields at output time t as a pyvista `UnstructuredGrid` on the mesh's nodes
        (triangles, quadrilaterals or tetrahedra; 2D points get z = 0).

        Point data: `displacement` (mm, 3 components), with a pore pressure `pore_pressure`
        (MPa; NaN outside the subcutaneous tissue, where there is none). Cell data: `region`
        (the tag: skin 1, subcutaneous 2, bone 3, nail 4) and the cell means of the
        discontinuous fields `strain_energy_density` (MPa), `log_strain` (the Hencky strain,
        gdim² components, row by row) and `principal_log_strain` (largest first);
        `grid.cell_data_to_point_data()` smooths them onto the nodes. `warp`: the points at
        the deformed positions X + u (True) or X + warp·u (a number: magnified); default the
        reference positions.
        """
        import pyvista as pv

        f = self.fields(t)
        cells, corners, gdim = f["X"].shape
        nodes, inverse = np.unique(f["X"].reshape(-1, gdim), axis=0, return_inverse=True)
        connectivity = inverse.reshape(cells, corners)
        u = np.zeros_like(nodes)
        u[connectivity] = f["u"]  # the same at a node shared by cells (continuous)
        points = nodes + float(warp) * u
        kind, order = _VTK_CELLS[corners, gdim]
        grid = pv.UnstructuredGrid(
            np.hstack([np.full((cells, 1), corners), connectivity[:, order]]).ravel(),
            np.full(cells, kind, dtype=np.uint8), _in_3d(points))
        grid.point_data["displacement"] = _in_3d(u)
        if "p" in f:
            grid.point_data["pore_pressure"] = _on_nodes(nodes, f["X_p"], f["p"])
        grid.cell_data["region"] = f["region"]
        grid.cell_data["strain_energy_density"] = f["sed"].mean(axis=1)[:, 0]
        grid.cell_data["log_strain"] = f["log_strain"].mean(axis=1)
        grid.cell_data["principal_log_strain"] = f["principal"].mean(axis=1)
        return grid


#: (corners, gdim) -> (VTK cell type, VTK order of the basix corners). Basix numbers a
#: quadrilateral's corners in tensor order (0, 1 on the first edge, 2, 3 opposite), VTK
#: counter-clockwise.
_VTK_CELLS = {(3, 2): (5, [0, 1, 2]), (4, 2): (9, [0, 1, 3, 2]), (4, 3): (10, [0, 1, 2, 3])}


def _in_3d(x: np.ndarray) -> np.ndarray:
    """Points or vectors with 3 components (2D ones get z = 0), as VTK wants them."""
    return np.hstack([x, np.zeros((len(x), 3 - x.shape[1]))]) if x.shape[1] < 3 else x


def _on_nodes(nodes: np.ndarray, X: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Corner values (cells, corners) of a continuous field on a submesh, at the mesh's
    `nodes` (np.unique-sorted); NaN at the nodes the submesh does not hold."""
    corners = X.reshape(-1, nodes.shape[1])
    merged, inverse = np.unique(np.concatenate([nodes, corners]), axis=0, return_inverse=True)
    if len(merged) != len(nodes):
        raise ValueError("the submesh's corners are not nodes of the mesh")
    out = np.full(len(nodes), np.nan)
    out[inverse.ravel()[len(nodes):]] = values.ravel()
    return out


class FrequencyResult:
    """The frequency route's results in `out` (frequency_response.py), as arrays.

    - `summary`: summary.json as a dict (scene, pressed state, mesh, dofs, resonances, ...);
    - `response`: frequency_response.csv, columns as arrays (`frequency_Hz`,
      `K_abs_N_per_mm2`, `K_phase_deg`, `Z_abs_Ns_per_mm2`, `Z_phase_deg`, ... in plane
      strain; `K_abs_N_per_mm` and `Z_abs_Ns_per_mm` in 3D);
    - `frequencies` (Hz), `stiffness` K(ω) = δf/δd and `impedance` Z(ω) = δf/(iω δd) at them
      (complex; per mm of thickness in plane strain: N/mm per mm and N·s/mm per mm; in 3D
      N/mm and N·s/mm, a half model's own: `summary["mirror_factor"]`);
    - `transfer`: receptor_transfer.csv, per frequency and receptor site the amplitude per µm
      of drive and phase of each stimulus quantity (`class` strings, `index` integers);
    - `thresholds`: thresholds.csv, per class, site and frequency the afferent thresholds
      `I0_um` (absolute) and `I1_um` (1:1 entrainment) in µm of probe displacement;
    - `pressed`: receptors.csv, the stimulus quantities at the sites in the pressed state.
    """

    route = "frequency"

    def __init__(self, out: str | Path):
        self.out = Path(out)
        if not (self.out / "frequency_response.csv").exists():
            raise InputError(str(self.out), "holds no frequency response (no "
                             "frequency_response.csv).", "give the --out directory of a run "
                             "on the frequency route (--frequencies or a [harmonic] table).")

    def __repr__(self) -> str:
        return (f"FrequencyResult({str(self.out)!r}: {self.summary['scene']['name']}, "
                f"{len(self.frequencies)} frequencies, {self.summary['dofs']} dofs)")

    @cached_property
    def summary(self) -> dict:
        return json.loads((self.out / "summary.json").read_text())

    @cached_property
    def response(self) -> dict[str, np.ndarray]:
        return read_csv(self.out / "frequency_response.csv")

    @property
    def frequencies(self) -> np.ndarray:
        return self.response["frequency_Hz"]

    @property
    def stiffness(self) -> np.ndarray:
        return self.response["K_real"] + 1j * self.response["K_imag"]

    @property
    def impedance(self) -> np.ndarray:
        r = self.response
        magnitude = next(k for k in r if k.startswith("Z_abs_"))  # named by its unit
        return r[magnitude] * np.exp(1j * np.radians(r["Z_phase_deg"]))

    @cached_property
    def transfer(self) -> dict[str, np.ndarray]:
        return _read_table(self.out / "receptor_transfer.csv", ("class",), ("index",))

    @cached_property
    def thresholds(self) -> dict[str, np.ndarray]:
        return _read_table(self.out / "thresholds.csv", ("class",), ("index",))

    @cached_property
    def pressed(self) -> dict[str, np.ndarray]:
        return _read_table(self.out / "receptors.csv", ("class",), ("index",))


def load_result(out: str | Path) -> Result | FrequencyResult:
    """The results of the run written into `out`.

    Parameters
    ----------
    out : str or Path
        The run's output folder.

    Returns
    -------
    Result or FrequencyResult
        A `FrequencyResult` for the frequency route's files, else a `Result`.
    """
    out = Path(out)
    if (out / "frequency_response.csv").exists() and not (out / "history.csv").exists():
        return FrequencyResult(out)
    return Result(out)


def _read_if_there(path: Path) -> dict[str, np.ndarray]:
    return read_csv(path) if path.exists() else {}


def _read_table(path: Path, text=(), integer=()) -> dict[str, np.ndarray]:
    """A CSV file's columns: those in `text` as strings, in `integer` as integers, the others
    as floats (empty cells NaN)."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}

    def column(k):
        values = [r[k] for r in rows]
        if k in text:
            return np.array(values)
        if k in integer:
            return np.array([int(v) for v in values])
        return np.array([float(v) if v != "" else np.nan for v in values])

    return {k: column(k) for k in rows[0]}
