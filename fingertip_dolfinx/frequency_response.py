r"""The frequency route of a scene: pressed state, then the small-signal response per frequency
(harmonic.py), written as tables, a summary and figures.

`run_frequency_response(scene, out, frequencies, state)`:

1. the pressed state: the protocol's pre-indentation (`loading.Vibration.pressing`, or a
   `RampHold` protocol itself), "held" at its end or "relaxed" (harmonic.press);
2. the linearisation and one LU per frequency (harmonic.HarmonicSolver);
3. per frequency a row of frequency_response.csv: the dynamic stiffness K(ω) = δf/δd and the
   driving-point impedance Z(ω) = δf/(iω δd), magnitude and phase (degrees; a phase > 0: the
   force leads the drive); N/mm per mm and N·s/mm per mm in plane strain, N/mm and N·s/mm in
   3D (a half model's own), the columns named by their units (`response_columns`);
4. per frequency and receptor site a row of receptor_transfer.csv: the transfer functions from
   the drive to the stimulus quantities of `receptors.QUANTITIES` (sed, compressive_strain =
   −e_min, compressive_stress = −σ22 total), amplitude per µm of drive and phase (degrees), at
   the sites of the scene's `[output] receptors` set ("default" if none);
5. the afferent thresholds these transfer functions give (`vibrotactile.vibration_thresholds`
   per class, the class's quantity H(ω) at each of its sites and its pressed value s0 from
   receptors.csv, the stimulus quantities at the sites in the pressed state): thresholds.csv,
   one row per class, site and frequency, with I0 (absolute) and I1 (1:1 entrainment) in µm of
   probe displacement (NaN where s0 alone fires, inf where the site cannot follow);
6. summary.json (pressed state, mesh, dofs, timings, the resonances the grid resolves,
   `resonances`, and where it does not, the bands to refine: `resonance_warning`) and the
   figures impedance.png (Bode plot of Z at the computed frequencies, resonances and
   unresolved bands marked), receptor_transfer_<class>.png (amplitude over position and
   frequency) and thresholds.png (the most sensitive site's I0 and I1 per class, with the
   verified published bands, `vibrotactile.PUBLISHED`).

**Transfer functions** (`SiteTransfer`). Each quantity q is a nonlinear function of the state;
its small-signal change is the directional derivative δq = Dq[δu] (and −δp for the total
stress), computed exactly with `ufl.derivative` at the pressed state, applied to δu_r and δu_i
separately (q is real: δq = Dq[δu_r] + i Dq[δu_i]). Exact derivatives need no step ε (central
differences q(u0 ± ε δu) would trade an O(ε²) truncation against round-off in the small
difference of large values; sed is quadratic in the strain, small at small depth). The stress
of a QLV law is P Fᵀ/J with P = F S: δσ = Dσ[δu]|_{S0 frozen history} + (G*(ω) − g∞) F DS_e[δu]
Fᵀ/J, since δS = G* DS_e[δu] while the frozen-history derivative carries g∞ DS_e. The fields are
brought to the sites as the receptor recorder's are: sed and e_min interpolated into DG1, the
stress projected from the quadrature points into DG1 (post.QuadratureProjection), then
sampled (post.PointSampler).
"""

from __future__ import annotations

import dataclasses
import math
import time as wallclock
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from matplotlib.figure import Figure
from mpi4py import MPI
from ufl.algorithms import expand_derivatives

from .afferents.receptors import (
    CLASSES,
    QUANTITIES,
    ReceptorRecorder,
    load_receptors,
    pressure_sampling,
    surface_sites,
)
from .afferents.vibrotactile import plot_threshold_curves, vibration_thresholds
from .errors import InputError, on_root
from .geometry.fingertip3d import Fingertip3D
from .geometry.mesh import build_mesh
from .geometry.mesh3d import build_mesh3d
from .harmonic import HarmonicSolver, complex_modulus, linearise, press
from .harmonic_options import HarmonicOptions, parse_frequencies
from .loading import RampHold, Vibration
from .outputs import CsvLog, prepare_directory, write_json
from .physics.kinematics import principal_log_strains
from .plotting.figures import fitted, plain_log_ticks
from .post import DerivedFields, PointSampler, QuadratureProjection, accepted_stress
from .problem import FingertipProblem
from .scene import Scene, scene_record

#: frequency_response.csv's columns in plane strain, where K is a force per unit thickness
#: per mm of drive (N/mm per mm) and Z one per mm/s (N·s/mm per mm); `response_columns`.
RESPONSE_COLUMNS = ("frequency_Hz", "K_abs_N_per_mm2", "K_phase_deg", "Z_abs_Ns_per_mm2",
                    "Z_phase_deg", "K_real", "K_imag", "solve_s")
TRANSFER_COLUMNS = ("frequency_Hz", "class", "index", "x_mm", "depth_mm", *(
    f"{q}_{part}" for q in QUANTITIES for part in ("abs_per_um", "phase_deg")))
THRESHOLD_COLUMNS = ("class", "index", "x_mm", "depth_mm", "frequency_Hz", "s0",
                     "H_abs_per_um", "I0_um", "I1_um")
#: Drive unit of the transfer tables: per µm of indenter motion.
PER_UM = 1e-3
#: A 3D population's thresholds: of this many sites per class, the most responsive
#: (`responsive_sites`); the transfer table keeps every site.
THRESHOLD_SITES_3D = 16


class SiteTransfer:
    """The transfer functions from the drive to the stimulus quantities at fixed points (see
    the module's docstring). Collective: every rank calls it; values on rank 0."""

    def __init__(self, problem, points: np.ndarray):
        F, msh = problem.F, problem.mesh
        self.problem = problem
        self.du = fem.Function(problem.V)
        scalar = fem.functionspace(msh, ("Discontinuous Lagrange", 1))
        ipoints = scalar.element.interpolation_points
        self.sed, self.e_min = fem.Function(scalar), fem.Function(scalar)
        self._scalars, stress, material = [], [], []
        for name, law in problem.laws.regions.items():
            cells = problem.fmesh.cell_tags.find(problem.tags[name])
            if not law.rigid:
                self._scalars.append((self.sed, cells, fem.Expression(
                    self._d(law.energy), ipoints)))
            sigma = accepted_stress(law, F) * F.T / ufl.det(F)
            stress.append((cells, self._d(sigma)))
            if law.history is not None:  # each QLV region: its own G*(ω)
                material.append((law.history.prony, cells,
                                 F * self._d(law.history.S_e) * F.T / ufl.det(F)))
        self._min_strain_plan(F, ipoints)
        degree = problem.options.quadrature_degree
        self.stress = QuadratureProjection(msh, stress, degree, "d_sigma")
        #: (Prony series, projection of its region's F DS_e[δu] Fᵀ/J) per QLV region.
        self.material = [(prony, QuadratureProjection(msh, [(cells, expr)], degree,
                                                      f"d_sigma_material{k}"))
                         for k, (prony, cells, expr) in enumerate(material)]
        self.sampler = PointSampler(msh, points)
        self._pressure_sampling(problem, points)

    def _min_strain_plan(self, F, ipoints) -> None:
        """δe_min, the derivative of the receptor recorder's e_min (post.DerivedFields). 2D: of
        the UFL principal value. 3D: e_min = ½ ln c_min of b = F Fᵀ at the DG1 nodes (numpy's
        eigensolver), so δe_min = n·δb·n/(2 c_min) there, n the unit eigenvector of c_min at
        the pressed state (a simple eigenvalue) and δb = δF F0ᵀ + F0 δFᵀ."""
        msh = self.problem.mesh
        tdim = msh.topology.dim
        self._b_min = None
        if tdim == 2:
            every = np.arange(msh.topology.index_map(2).size_local
                              + msh.topology.index_map(2).num_ghosts, dtype=np.int32)
            self._scalars.append((self.e_min, every, fem.Expression(
                self._d(principal_log_strains(F)[1]), ipoints)))
            return
        tensor = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (3, 3)))
        b0 = fem.Function(tensor)
        b0.interpolate(fem.Expression(F * F.T, tensor.element.interpolation_points))
        c, n = np.linalg.eigh(b0.x.array.reshape(-1, 3, 3))  # ascending c
        self._b_min = (c[:, 0], n[:, :, 0])
        self._db = fem.Function(tensor)
        self._db_expr = fem.Expression(self._d(F * F.T), tensor.element.interpolation_points)

    def _update_min_strain(self) -> None:
        """3D: δe_min at the DG1 nodes from the interpolated δb (see `_min_strain_plan`)."""
        if self._b_min is None:
            return
        c, n = self._b_min
        self._db.interpolate(self._db_expr)
        db = self._db.x.array.reshape(-1, 3, 3)
        self.e_min.x.array[:] = np.einsum("ki,kij,kj->k", n, db, n) / (2 * c)

    def _d(self, expr):
        """Dq[δu] as UFL, δu the Function `du`."""
        return expand_derivatives(ufl.derivative(expr, self.problem.u, self.du))

    def _pressure_sampling(self, problem, points) -> None:
        self.pressure, self.in_tissue = pressure_sampling(problem, self.sampler, points)
        self.dp = None if problem.p is None else fem.Function(problem.p.function_space)

    def _real_part(self, arrays: list[np.ndarray]) -> dict[str, np.ndarray] | None:
        """Dq[δ] at the points for one real direction δ = (δu, δp)."""
        self.du.x.array[:] = arrays[0]
        for f, cells, expr in self._scalars:
            f.interpolate(expr, cells0=cells)
        self._update_min_strain()
        for f in (self.sed, self.e_min):
            f.x.scatter_forward()
        self.stress.update()
        values = {"sed": self.sampler(self.sed), "e_min": self.sampler(self.e_min),
                  "sigma22": self.sampler(self.stress.stress)}
        for k, (_, projection) in enumerate(self.material):
            projection.update()
            values[f"material22_{k}"] = self.sampler(projection.stress)
        if self.dp is not None:
            self.dp.x.array[:] = arrays[1]
            values["p"] = self.pressure(self.dp)
        if self.problem.mesh.comm.rank != 0:
            return None
        yy = self.problem.mesh.geometry.dim + 1  # σ22 in the row-by-row (d, d) tensor
        out = {"sed": values["sed"][:, 0], "e_min": values["e_min"][:, 0],
               "sigma22": values["sigma22"][:, yy]}
        for k in range(len(self.material)):
            out[f"material22_{k}"] = values[f"material22_{k}"][:, yy]
        out["p"] = (np.where(self.in_tissue, values["p"][:, 0], 0.0) if "p" in values
                    else np.zeros_like(out["sed"]))
        return out

    def __call__(self, response) -> dict[str, np.ndarray] | None:
        """{quantity: complex values per mm of drive, compression > 0} on rank 0 (None
        elsewhere), the quantities of receptors.QUANTITIES."""
        r, i = self._real_part(response.x_r), self._real_part(response.x_i)
        if r is None:
            return None
        c = {k: r[k] + 1j * i[k] for k in r}
        sigma22 = c["sigma22"]
        for k, (prony, _) in enumerate(self.material):  # (G*(ω) − g∞) F DS_e[δu] Fᵀ/J
            sigma22 = sigma22 + (complex_modulus(prony, response.omega) - prony.g_inf) * c[
                f"material22_{k}"]
        sigma22 = sigma22 - c["p"]
        values = {"sed": c["sed"], "compressive_strain": c["e_min"],
                  "compressive_stress": sigma22}
        return {q: QUANTITIES[q][1] * values[q] for q in QUANTITIES}


# --- the run --------------------------------------------------------------------------------


def pressing_of(scene: Scene) -> RampHold:
    """The pre-indentation of the scene's protocol: a Vibration's `pressing`, or a RampHold.
    Frictional indenters are refused: the linearisation has no friction term."""
    if any(i.friction > 0 for i in scene.indenters):
        raise InputError(f"{scene.name}: indenters.friction", "the frequency response is "
                         "linearised about a frictionless contact.",
                         "set friction = 0 for the frequency route, or run in time.")
    history = scene.history
    if isinstance(history, Vibration):
        return history.pressing
    if isinstance(history, RampHold):
        return history
    raise InputError(f"{scene.name}: protocol", "the frequency response needs a pressed state: "
                     f"a {type(history).__name__} protocol has none.",
                     'use kind = "vibration" (or "ramp-hold").')


def frequencies_of(scene: Scene, options: HarmonicOptions) -> tuple[float, ...]:
    if options.frequencies:
        return options.frequencies
    if isinstance(scene.history, Vibration):
        return scene.history.frequencies
    raise InputError(f"{scene.name}: harmonic.frequencies", "none given.",
                     'give --frequencies 1:1000:40 or [harmonic] frequencies = "1:1000:40".')


def run_frequency_response(scene: Scene, out: str | Path, *, frequencies=None,
                           state: str | None = None, progress: bool = True,
                           comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """The frequency route of `scene` into `out` (see the module's docstring); returns the
    summary. `frequencies` (a harmonic_options.parse_frequencies spec) and `state` override the
    scene's `[harmonic]` table."""
    options = scene.harmonic or HarmonicOptions()
    if frequencies is not None:
        options = dataclasses.replace(options, frequencies=frequencies)
    if state is not None:
        options = dataclasses.replace(options, state=state)
    freqs = frequencies_of(scene, options)
    pressing = pressing_of(scene)
    population = load_receptors(scene.outputs.receptors or "default")
    out = prepare_directory(Path(out), comm)
    started = wallclock.perf_counter()
    fm, sites = mesh_and_sites(scene, population, comm)
    problem = FingertipProblem(fm, scene.indenters, scene.history, scene.materials, scene.model)
    dofs = sum(f.function_space.dofmap.index_map.size_global
               * f.function_space.dofmap.index_map_bs for f in problem.unknowns)
    show = _printer(progress, comm)
    show(f"{scene.name}: {dofs} dofs; pressing to {pressing.depth:g} mm ({options.state})")
    pressed = press(problem, pressing, options.state, scene.steps, scene.petsc_options,
                    linear=scene.linear)
    show(f"pressed: {pressed.force:.4g} {force_unit(problem)} after {pressed.steps} steps "
         f"({pressed.wall_time_s:.1f} s)")
    pressed_sites = record_pressed_sites(problem, population, scene, out, comm, pressed.time,
                                         sites)
    solver = HarmonicSolver(linearise(problem))
    at = sites.points if sites.sample_points is None else sites.sample_points
    try:
        rows, site_rows, transfers = _sweep(solver, SiteTransfer(problem, at), sites,
                                            freqs, out, comm, show, force_unit(problem))
    finally:
        solver.close()
    most = None if sites.sample_points is None else THRESHOLD_SITES_3D
    curves = on_root(comm, lambda: afferent_thresholds(population, sites, freqs, transfers,
                                                       pressed_sites, out / "thresholds.csv",
                                                       most_responsive=most))
    show(f"thresholds at {len(freqs)} frequencies: thresholds.csv")
    summary = _summary(scene, fm, dofs, pressed, solver, rows, options, comm,
                       wallclock.perf_counter() - started)
    summary["force_unit"] = force_unit(problem)
    summary["mirror_factor"] = problem.mirror_factor
    write_json(out / "summary.json", summary, comm)
    if scene.outputs.pictures:  # every file is written when any rank returns (rank 0 draws)
        on_root(comm, lambda: _figures(rows, site_rows, curves, population, scene, options,
                                       pressing, summary, out))
    return summary


def mesh_and_sites(scene: Scene, population, comm):
    """The scene's mesh and the population's sites on it: one row per class along the
    section in 2D, over the pulp surface of the whole finger in 3D (`surface_sites`; a half
    model's mirrored sites read their mirror images, `Sites.sample_points`)."""
    if isinstance(scene.section, Fingertip3D):
        fm = build_mesh3d(scene.section, comm)
        return fm, surface_sites(population, fm, scene.section.half)
    return build_mesh(scene.section, comm), population.sites(scene.section.outer)


def force_unit(problem) -> str:
    """The unit of the indenter force and of K(ω) = δf/δd: per mm of thickness in plane
    strain; in 3D the model's own (a half model's: half the whole finger's, `mirror_factor`)."""
    if problem.mesh.geometry.dim == 2:
        return "N/mm"
    return "N (half model)" if problem.mirror_factor == 2 else "N"


def response_columns(unit: str) -> tuple[str, ...]:
    """frequency_response.csv's columns for the force unit `unit` (`force_unit`): |K| and |Z|
    named by their units, N/mm per mm and N·s/mm per mm in plane strain (RESPONSE_COLUMNS),
    N/mm and N·s/mm in 3D (a half model's own: summary.json's `mirror_factor`)."""
    if unit == "N/mm":
        return RESPONSE_COLUMNS
    return tuple(c.replace("_per_mm2", "_per_mm") for c in RESPONSE_COLUMNS)


def magnitude_key(row: dict, quantity: str) -> str:
    """The column of |K| or |Z| (`quantity`: "K" or "Z") in a row of frequency_response.csv,
    whichever unit names it (`response_columns`)."""
    return next(k for k in row if k.startswith(f"{quantity}_abs_"))


def _sweep(solver, transfer, sites, freqs, out: Path, comm, show, unit: str
           ) -> tuple[list, list, list]:
    """One solve per frequency, each written as it comes: a row of frequency_response.csv (its
    columns named for the force unit `unit`) and the sites' rows of receptor_transfer.csv.
    Returns (response rows, site rows, the transfer functions per frequency)."""
    columns = response_columns(unit)
    response_log = CsvLog(out / "frequency_response.csv", columns, comm)
    transfer_log = CsvLog(out / "receptor_transfer.csv", site_columns(TRANSFER_COLUMNS, sites),
                          comm)
    rows, site_rows, transfers = [], [], []
    try:
        for k, f in enumerate(freqs):
            r = solver.solve(f)
            rows.append(response_row(r, columns))
            response_log.write([rows[-1]])
            transfers.append(transfer(r))
            site_rows += transfer_rows(f, transfers[-1], sites)
            transfer_log.write(site_rows[len(site_rows) - len(sites):] if comm.rank == 0 else [])
            show(f"[{k + 1}/{len(freqs)}] {f:.4g} Hz: |Z| = {abs(r.impedance):.4g} "
                 f"{impedance_unit(unit)}, "
                 f"phase {math.degrees(np.angle(r.impedance)):.1f}° ({r.wall_time_s:.2f} s)")
    finally:
        response_log.close()
        transfer_log.close()
    return rows, site_rows, transfers


def _figures(rows, site_rows, curves, population, scene, options, pressing, summary,
             out: Path) -> None:
    """impedance.png, receptor_transfer_<class>.png and thresholds.png (rank 0)."""
    plot_impedance(rows, out / "impedance.png", scene.name, summary["force_unit"])
    if not isinstance(scene.section, Fingertip3D):  # 3D sites are not a row along x
        plot_receptor_transfer(site_rows, out, population, scene.name)
    plot_threshold_curves(curves, out / "thresholds.png", title=(
        f"{scene.name}, {options.state} at {pressing.depth:g} mm: most sensitive site"),
        note=summary["resonance_warning"])


def small_signal_response(scene: Scene, frequencies, state: str = "held",
                          comm: MPI.Comm = MPI.COMM_WORLD) -> tuple:
    """(pressed state, [harmonic.Response per frequency]) of `scene`, nothing written: the
    reference for a time-domain run of the same scene. For a drive d(t) = d0 + A sin(ωt) the
    steady force is f(t) = f0 + |K(ω)| A sin(ωt + arg K(ω)) (`Response.stiffness`), valid while
    A is small against the depth and the contact zone does not change. "held" matches a run
    that vibrates from the end of the protocol's hold (its drift frozen there)."""
    problem = FingertipProblem(build_mesh(scene.section, comm), scene.indenters, scene.history,
                               scene.materials, scene.model)
    pressed = press(problem, pressing_of(scene), state, scene.steps, scene.petsc_options,
                    linear=scene.linear)
    solver = HarmonicSolver(linearise(problem))
    try:
        return pressed, solver.sweep(parse_frequencies(frequencies))
    finally:
        solver.close()


def record_pressed_sites(problem, population, scene, out: Path, comm, t: float,
                         sites=None):
    """The stimulus quantities at the population's `sites` (default: the section's rows) in
    the pressed state, written as receptors.csv (one row per site, time = the pressed state's)
    and returned (rank 0; None elsewhere): the s0 the probe vibrates about."""
    derived = DerivedFields(problem.u, problem.fmesh.cell_tags, problem.region_energies())
    recorder = ReceptorRecorder(problem, derived, population, scene.section.outer, out, comm,
                                sites=sites)
    try:
        rows = recorder.sample(t)
        if rows is not None:
            recorder.log.write(rows)
        return rows
    finally:
        recorder.close()


def afferent_thresholds(population, sites, freqs, transfers: list[dict], pressed: list[dict],
                        path: Path, most_responsive: int | None = None) -> list:
    """Per class, `vibrotactile.vibration_thresholds` of the mechanics' transfer functions at
    the class's sites (H: the class's quantity per mm of drive, `transfers` per frequency) about
    their pressed values (`pressed`: receptors.csv rows); thresholds.csv written (rank 0).
    `most_responsive`: only that many sites per class, those of largest peak |H| over the
    frequencies (`responsive_sites`). Returns the VibrationThresholds, one per class present."""
    curves, rows = [], []
    for cls in population.classes:
        mine = np.flatnonzero(sites.cls == cls.name)
        if len(mine) == 0:
            continue
        column, sign, _ = QUANTITIES[cls.quantity]
        # transfers carry the compression-positive sign already (SiteTransfer)
        h = np.array([t[cls.quantity][mine] for t in transfers])
        keep = responsive_sites(h, most_responsive)
        mine, h = mine[keep], h[:, keep]
        s0 = np.array([sign * pressed[i][column] for i in mine])
        th = vibration_thresholds(cls, freqs, h, s0)
        curves.append(th)
        for j, f in enumerate(freqs):
            rows += [{"class": cls.name, "index": int(sites.index[i]), **site_position(sites, i),
                      "depth_mm": sites.depth[i], "frequency_Hz": f, "s0": s0[k],
                      "H_abs_per_um": abs(h[j, k]) * PER_UM,
                      "I0_um": th.absolute[j, k] / PER_UM,
                      "I1_um": th.entrainment[j, k] / PER_UM} for k, i in enumerate(mine)]
    log = CsvLog(path, site_columns(THRESHOLD_COLUMNS, sites), MPI.COMM_SELF)
    try:
        log.write(rows)
    finally:
        log.close()
    return curves


def responsive_sites(h: np.ndarray, most: int | None) -> np.ndarray:
    """Indices (ascending) of the `most` columns of the transfers h (frequencies × sites) with
    the largest peak |H| (all if None). A site's thresholds scale as 1/|H| about a similar
    pressed value, so these hold the most sensitive afferent of a 3D population (~1,000 sites
    whose threshold search would take ~30× the section's)."""
    if most is None or h.shape[1] <= most:
        return np.arange(h.shape[1])
    return np.sort(np.argsort(-np.abs(h).max(axis=0), kind="stable")[:most])


def site_columns(columns: tuple, sites) -> tuple:
    """`columns` with y_mm, z_mm after x_mm for 3D sites (their reference position)."""
    if sites.points.shape[1] == 2:
        return columns
    k = columns.index("x_mm") + 1
    return (*columns[:k], "y_mm", "z_mm", *columns[k:])


def site_position(sites, i: int) -> dict:
    """x_mm of site i (2D: the surface point's x), and y_mm, z_mm in 3D (the site's own)."""
    if sites.points.shape[1] == 2:
        return {"x_mm": sites.x[i]}
    x, y, z = sites.points[i]
    return {"x_mm": x, "y_mm": y, "z_mm": z}


def response_row(r, columns: tuple[str, ...] = RESPONSE_COLUMNS) -> dict:
    """One frequency's row of frequency_response.csv (`columns`: `response_columns`)."""
    K, Z = r.stiffness, r.impedance
    values = (r.frequency, abs(K), math.degrees(np.angle(K)), abs(Z),
              math.degrees(np.angle(Z)), K.real, K.imag, r.wall_time_s)
    return dict(zip(columns, values, strict=True))


def transfer_rows(frequency: float, values: dict | None, sites) -> list[dict]:
    """One row per site (rank 0; empty elsewhere): amplitude per µm of drive and phase."""
    if values is None:
        return []
    rows = []
    for i in range(len(sites)):
        row = {"frequency_Hz": frequency, "class": sites.cls[i], "index": int(sites.index[i]),
               **site_position(sites, i), "depth_mm": sites.depth[i]}
        for q, v in values.items():
            row[f"{q}_abs_per_um"] = abs(v[i]) * PER_UM
            row[f"{q}_phase_deg"] = math.degrees(np.angle(v[i]))
        rows.append(row)
    return rows


#: A sampled peak is resolved when both its neighbours lie in its half-power band (|K|, or
#: |1/K|, at least 1/√2 of the peak's: the grid is finer than the peak's half width, and the
#: parabola through the three samples places it), or when its neighbours are within
#: ±RESONANCE_PRECISION of it (a peak sharper than the grid, but bracketed that closely).
HALF_POWER = 1 / math.sqrt(2)
RESONANCE_PRECISION = 0.02


def resonances(rows: list[dict]) -> dict[str, list]:
    """The resonances the sweep resolves (see HALF_POWER), Hz: "probe_held", maxima of |K|
    (poles of K: the fingertip's natural frequencies with the probe's motion prescribed, the
    drive here, where the receptor transfers peak; |Z| maxima) and "force_driven", maxima of
    the compliance |1/K| (zeros of K: the natural frequencies under a force drive; |Z|
    minima). A local maximum the grid does not resolve is not reported as a frequency but in
    "unresolved": {"kind", "sampled_Hz", "refine_Hz": [its neighbours]}. A sweep can still
    step over a peak without seeing it: no sampled maximum, nothing said."""
    f = np.array([r["frequency_Hz"] for r in rows])
    k = np.array([r[magnitude_key(r, "K")] for r in rows])
    found = {"probe_held": [], "force_driven": [], "unresolved": []}
    for kind, level in (("probe_held", k), ("force_driven", 1 / k)):
        for i in range(1, len(f) - 1):
            if level[i] <= max(level[i - 1], level[i + 1]):
                continue
            near = f[i + 1] / f[i - 1] <= (1 + RESONANCE_PRECISION) / (1 - RESONANCE_PRECISION)
            if near or min(level[i - 1], level[i + 1]) >= HALF_POWER * level[i]:
                found[kind].append(_peak(f[i - 1:i + 2], level[i - 1:i + 2]))
            else:
                found["unresolved"].append({"kind": kind, "sampled_Hz": float(f[i]),
                                            "refine_Hz": [float(f[i - 1]), float(f[i + 1])]})
    return found


def _peak(f: np.ndarray, level: np.ndarray) -> float:
    """The vertex of the parabola through three samples (log level over log f), the middle
    one highest: inside the outer two."""
    x, y = np.log(f), np.log(level)
    d1, d2 = (y[1] - y[0]) / (x[1] - x[0]), (y[2] - y[1]) / (x[2] - x[1])
    curvature = (d2 - d1) / (x[2] - x[0])  # < 0
    return float(np.exp(0.5 * (x[0] + x[1]) - d1 / (2 * curvature)))


def unresolved_bands(found: dict) -> list[tuple[float, float]]:
    """The bands to refine: the unresolved peaks' neighbours (both kinds), overlaps joined."""
    bands = []
    for lo, hi in sorted(tuple(u["refine_Hz"]) for u in found["unresolved"]):
        if bands and lo <= bands[-1][1]:
            bands[-1] = (bands[-1][0], max(hi, bands[-1][1]))
        else:
            bands.append((lo, hi))
    return bands


def resolution_warning(found: dict) -> str:
    """"not resolved by the grid: refine near 10–464 Hz" for the unresolved peaks of
    `resonances` (`unresolved_bands`), "" if none."""
    bands = unresolved_bands(found)
    if not bands:
        return ""
    return "not resolved by the grid: refine near " + ", ".join(
        f"{lo:.3g}–{hi:.3g}" for lo, hi in bands) + " Hz"


def _summary(scene, fm, dofs, pressed, solver, rows, options, comm, wall) -> dict:
    solves = [r["solve_s"] for r in rows]
    found = resonances(rows)
    return {
        "scene": scene_record(scene),
        "harmonic": {"state": options.state, "frequencies_Hz": [r["frequency_Hz"] for r in rows]},
        "pressed_state": pressed.record(),
        "mesh": _mesh_record(fm.report),
        "dofs": dofs,
        "ranks": comm.size,
        "assembly_s": solver.assembly_time_s,
        "solve_s_total": float(np.sum(solves)),
        "solve_s_mean": float(np.mean(solves)) if solves else math.nan,
        "wall_time_s": wall,
        "resonances_Hz": {k: found[k] for k in ("probe_held", "force_driven")},
        "resonances_unresolved": found["unresolved"],
        "resonance_warning": resolution_warning(found),
    }


def _mesh_record(r) -> dict | None:
    if r is None:
        return None
    return {"cells": r.num_cells, "cell_type": r.cell_type, "min_edge_mm": r.min_edge,
            "max_edge_mm": r.max_edge, "min_quality": r.min_quality}


def _printer(progress: bool, comm):
    def show(text: str) -> None:
        if progress and comm.rank == 0:
            print(text, flush=True)
    return show


# --- figures ----------------------------------------------------------------------------------


def plot_impedance(rows: list[dict], path: Path, title: str = "",
                   force: str = "N/mm") -> Path:
    """Bode plot of the driving-point impedance Z(ω): |Z| and its phase at the computed
    frequencies (markers only: a line between two samples would claim a curve that was not
    computed, across resonances), log axes; the resolved resonances as vertical lines, and the
    bands where the grid does not resolve a peak shaded, with the warning below the axes.
    `force`: the force's unit (`force_unit`), which gives |Z|'s: force per mm/s."""
    f = np.array([r["frequency_Hz"] for r in rows])
    found = resonances(rows)
    fig = Figure(figsize=(6.4, 6.4))
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.loglog(f, [r[magnitude_key(r, "Z")] for r in rows], "o", ms=4, label="computed")
    top.set_ylabel(impedance_label(force))
    top.set_title(fitted(f"{title}: driving-point impedance" if title else
                         "driving-point impedance", fig))
    bottom.semilogx(f, [r["Z_phase_deg"] for r in rows], "o", ms=4)
    bottom.set_ylabel("phase of Z (°)")
    bottom.set_yticks([-90, -45, 0, 45, 90])
    bottom.set_xlabel("frequency (Hz)")
    plain_log_ticks(bottom, "x")
    styles = {"probe_held": ("tab:red", "--", "|K| max (probe held)"),
              "force_driven": ("tab:purple", ":", "|K| min (force driven)")}
    for kind, (colour, line, label) in styles.items():
        for j, fr in enumerate(found[kind]):
            for ax in (top, bottom):
                ax.axvline(fr, color=colour, ls=line, lw=1,
                           label=f"{label}: " + ", ".join(f"{v:.3g}" for v in found[kind])
                           + " Hz" if ax is top and j == 0 else None)
    for j, (lo, hi) in enumerate(unresolved_bands(found)):
        for ax in (top, bottom):
            ax.axvspan(lo, hi, color="tab:orange", alpha=0.15, lw=0, label=(
                "peak not resolved by the grid" if ax is top and j == 0 else None))
    for ax in (top, bottom):
        ax.grid(True, which="both", alpha=0.3)
    top.legend(fontsize=7, loc="best")
    warning = resolution_warning(found)
    fig.tight_layout(rect=(0, 0.05 if warning else 0, 1, 1))
    if warning:
        fig.text(0.5, 0.015, warning, ha="center", fontsize=8, color="tab:red", wrap=True)
    fig.savefig(path, dpi=120)
    return path


def impedance_unit(force: str) -> str:
    """Z's unit for the force unit `force_unit` gives: Z = δf/(iω δd) is a force per mm/s, so
    N·s/mm per mm of thickness in plane strain and N·s/mm in 3D."""
    return "N·s/mm per mm" if force == "N/mm" else "N·s/mm"


def impedance_label(force: str) -> str:
    """|Z|'s axis label for the force unit `force`, a half model's named."""
    return f"|Z| of the half model ({impedance_unit(force)})" if "half" in force else \
        f"|Z| ({impedance_unit(force)})"


def plot_receptor_transfer(rows: list[dict], out: Path, population,
                           title: str = "") -> list[Path]:
    """Per receptor class: the amplitude of the stimulus quantity its model reads, per µm of
    drive, over the sites' position x and the frequency (log colour scale). Each computed
    (site, frequency) is one cell, its edges halfway between neighbours (geometric means in
    frequency, on the log axis), so no cell is wider than its sample's share. `rows`: those of
    receptor_transfer.csv."""
    from matplotlib.colors import LogNorm

    data = {k: np.array([r[k] for r in rows]) for k in TRANSFER_COLUMNS}
    paths = []
    for cls in CLASSES:
        mine = data["class"] == cls
        if not np.any(mine):
            continue
        x, f = np.unique(data["x_mm"][mine]), np.unique(data["frequency_Hz"][mine])
        fig = Figure(figsize=(6.4, 4.8))
        ax = fig.subplots()
        quantity = population[cls].quantity
        z = np.full((len(f), len(x)), np.nan)
        z[np.searchsorted(f, data["frequency_Hz"][mine]),
          np.searchsorted(x, data["x_mm"][mine])] = data[f"{quantity}_abs_per_um"][mine]
        z = np.ma.masked_where(~(z > 0), z)  # a zero amplitude has no colour on a log scale
        name = quantity.replace("_", " ")
        if z.count():
            mesh = ax.pcolormesh(_edges(x, log=False), _edges(f, log=True), z,
                                 norm=LogNorm(vmin=z.min(), vmax=z.max()), shading="flat")
            fig.colorbar(mesh, ax=ax,
                         label=f"{name} amplitude ({QUANTITIES[quantity][2]} per µm)")
        else:  # none above zero (no first-order change, e.g. SED about rest): no log scale
            ax.set(xlim=_edges(x, log=False)[[0, -1]], ylim=_edges(f, log=True)[[0, -1]])
            ax.text(0.5, 0.5, f"{name}: zero (or not computed)\nat every site and frequency",
                    transform=ax.transAxes, ha="center", va="center")
        ax.set_yscale("log")
        plain_log_ticks(ax, "y")
        ax.set_xlabel("x of the site (mm)")
        ax.set_ylabel("vibration frequency (Hz)")
        depths = ", ".join(f"{d:g}" for d in np.unique(data["depth_mm"][mine]))
        ax.set_title(fitted(f"{title}: {cls} sites ({depths} mm deep), {name} per µm of drive"
                            if title else f"{cls} sites ({depths} mm deep), {name} per µm of "
                            "drive", fig, 9), fontsize=9)
        fig.tight_layout()
        paths.append(out / f"receptor_transfer_{cls}.png")
        fig.savefig(paths[-1], dpi=120)
    return paths


def _edges(centres: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted sample positions: midpoints (geometric with `log`), the outer
    edges as far out as the nearest inner one; one sample: a factor 1.2 (or ±0.5) around."""
    c = np.log(centres) if log else np.asarray(centres, dtype=float)
    if len(c) == 1:
        e = c[0] + np.array([-0.5, 0.5]) * (np.log(1.2) if log else 1.0)
    else:
        mid = 0.5 * (c[1:] + c[:-1])
        e = np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])
    return np.exp(e) if log else e
