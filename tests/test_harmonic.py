"""The frequency-domain route (harmonic.py) against exact answers and its own limits.

- The vibrating layer (studies.problems.VibratingLayer): a QLV hyperfoam layer on a rigid
  base, laterally confined, shaken at its top: the standing wave M* k cot(kH) in closed form.
  Over 1–1000 Hz (through its first resonances, with G* varying: a Prony series with fast
  terms, a test value) the computed dynamic stiffness matches to 1 % in amplitude and phase,
  and its error falls as h⁴ (P2: the nodal superconvergence of 1D Galerkin, h^{2p}).
- The fingertip (coarse 1pt mesh, the paper's materials, pressed 1 mm and relaxed): the drive
  vector is −∂R/∂d (a finite difference of the residual in the indenter's position); at
  ω → 0 Re K(ω) is the long-term tangent of two fully relaxed equilibria; at 2 Hz (ωτ_i ≫ 1,
  far below the tissue's resonances) it is the instantaneous tangent of a vanishing step.
"""

import math

import dolfinx.fem.petsc as fpetsc
import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.harmonic import (
    HarmonicSolver,
    complex_modulus,
    linearise,
    press,
    relaxation_steps,
    step_force,
)
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.physics.materials import Prony
from fingertip_dolfinx.physics.tissues import WU2004
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.studies.problems import VibratingLayer

COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0"]
#: Test value, not tissue data: fast Prony terms make G* vary over 1–1000 Hz.
FAST_PRONY = Prony((0.3, 0.2), (4e-3, 0.07))
DENSITY = 1.0e-9  # 1000 kg/m³
FREQUENCIES = np.geomspace(1.0, 1000.0, 25)


def test_complex_modulus_limits_and_causality():
    """G*(0) = g∞ (relaxed), G*(∞) = 1 (instantaneous), Im G* > 0 (dissipation) between."""
    p = FAST_PRONY
    assert complex_modulus(p, 0.0) == pytest.approx(p.g_inf, abs=1e-15)
    assert complex_modulus(p, 1e12) == pytest.approx(1.0, abs=1e-9)
    assert all(complex_modulus(p, w).imag > 0 for w in (1.0, 100.0, 1e4))


def _layer_errors(cells: int, frequencies) -> np.ndarray:
    layer = VibratingLayer(WU2004.skin, FAST_PRONY, DENSITY, cells=cells)
    solver = HarmonicSolver(layer.linearisation())
    try:
        return np.array([abs(1 / solver.solve(f).force / layer.exact_stiffness(f) - 1)
                         for f in frequencies])
    finally:
        solver.close()


def test_layer_matches_the_standing_wave():
    """|K_h/K − 1| < 1 % over 1–1000 Hz (bounds the amplitude's relative error and the phase's
    error in radians) on 40 P2 cells (8 per wavelength at 1000 Hz)."""
    errors = _layer_errors(40, FREQUENCIES)
    assert errors.max() < 1e-2, dict(zip(FREQUENCIES.round(1), errors))


def test_layer_profile_is_the_standing_wave():
    """The displacement along the column: sin(k y)/sin(k H), at 300 Hz (past the first
    resonance) to 1 % of the top's amplitude."""
    layer = VibratingLayer(WU2004.skin, FAST_PRONY, DENSITY, cells=40)
    solver = HarmonicSolver(layer.linearisation())
    response = solver.solve(300.0)
    solver.close()
    y = layer.V.tabulate_dof_coordinates()[:, 1]
    uy = response.displacement().reshape(-1, 2)[:, 1] / response.force  # per unit top motion
    exact = layer.exact_profile(y, 300.0)
    assert np.abs(uy - exact).max() < 1e-2


def test_layer_error_falls_at_the_p2_rate():
    """Halving h divides the error at 1000 Hz by ~16 (h^{2p}, p = 2; measured 16.1 and 16.0
    for 10 -> 20 -> 40 cells); assert at least P2's L2 rate h³."""
    errors = [_layer_errors(n, [1000.0])[0] for n in (10, 20, 40)]
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates > 3.0), (errors, rates)


# --- the fingertip ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def pressed():
    """The coarse 1pt fingertip pressed 1 mm in 1 s and relaxed; its harmonic solver."""
    scene = load_scene("1pt", COARSE)
    problem = FingertipProblem(build_mesh(scene.section), scene.indenters, scene.history,
                               scene.materials, scene.model)
    press(problem, RampHold(1.0, 1.0, 1.0), "relaxed", scene.steps)
    solver = HarmonicSolver(linearise(problem))
    yield problem, solver
    solver.close()


def _residual(problem, depth: float) -> np.ndarray:
    for obstacle in problem.obstacles:
        obstacle.y_tip.value = problem.y_touch + depth
    form = fem.form(problem.residuals[0], entity_maps=problem.entity_maps)
    vec = fpetsc.assemble_vector(form)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    values = vec.array_r.copy()
    vec.destroy()
    return values


@pytest.mark.mpi
def test_drive_is_minus_the_residuals_derivative_in_the_depth(pressed):
    """b = K_contact e_y (shift invariance) equals −∂R/∂d by central differences (ε = 1e-6 mm:
    truncation ~ε², round-off ~1e-16/ε of the residual's entries)."""
    problem, solver = pressed
    eps, depth = 1e-6, problem.indentation(problem.time)
    dR = (_residual(problem, depth + eps) - _residual(problem, depth - eps)) / (2 * eps)
    problem.set_time(problem.time)
    n = len(dR)  # this rank's owned displacement entries (the blocked vector's first part)
    b = solver.b.array_r[:n]
    free = np.ones(n, dtype=bool)
    clamped = problem.clamped_dofs[problem.clamped_dofs < n // 2]
    free[(clamped[:, None] * 2 + np.arange(2)).ravel()] = False
    comm = problem.mesh.comm
    norm_b = math.sqrt(comm.allreduce(float(b @ b)))
    error = math.sqrt(comm.allreduce(float(np.sum((b + dR)[free] ** 2))))
    assert norm_b > 0
    assert error < 1e-6 * norm_b


@pytest.mark.mpi
def test_zero_frequency_stiffness_is_the_long_term_tangent(pressed):
    """Re K(ω → 0) = (F(d + δ) − F(d − δ))/2δ of fully relaxed equilibria, to 1 % (measured
    1e-9). f = 1e-12 Hz: ω is far below the drainage rate (consolidation over the section
    ~7e7 s with the paper's k0 = 1e-3 mm⁴/(N s))."""
    problem, solver = pressed
    depth, delta = problem.indentation(problem.time), 1e-4
    steps = relaxation_steps(problem)
    tangent = (step_force(problem, depth + delta, steps)
               - step_force(problem, depth - delta, steps)) / (2 * delta)
    K = solver.solve(1e-12).stiffness
    assert K.real == pytest.approx(tangent, rel=1e-2)


@pytest.mark.mpi
def test_two_hertz_stiffness_is_the_instantaneous_tangent(pressed):
    """At 2 Hz (ωτ_i = 27 and 118 for the paper's τ = 2.1, 9.4 s; far above the drainage rate
    and below the first resonance) Re K = the tangent of one backward-Euler step of 1e-9 s
    (unrelaxed, undrained) to d ± δ, to 1 % (measured 0.1 %: G*(2 Hz) = 1 − 4e-4 − ...)."""
    problem, solver = pressed
    depth, delta = problem.indentation(problem.time), 1e-4
    tangent = (step_force(problem, depth + delta, [1e-9])
               - step_force(problem, depth - delta, [1e-9])) / (2 * delta)
    K = solver.solve(2.0).stiffness
    assert K.real == pytest.approx(tangent, rel=1e-2)
    assert K.imag > 0  # the skin's QLV dissipates: the force leads the drive


def test_impedance_is_the_stiffness_over_i_omega(pressed):
    _, solver = pressed
    r = solver.solve(10.0)
    assert r.impedance == pytest.approx(r.stiffness / (2j * math.pi * 10.0), rel=1e-14)


def test_bad_state_and_frequency_are_named(pressed):
    problem, solver = pressed
    with pytest.raises(InputError, match="harmonic.state"):
        press(problem, RampHold(1.0, 1.0, 1.0), "frozen")
    with pytest.raises(InputError, match="harmonic.frequencies"):
        solver.solve(-1.0)


# --- the frequency route of a scene -------------------------------------------------------------


def _sampled_quantities(problem, points) -> dict[str, np.ndarray]:
    """sed, −e_min and −σ22 total at `points` at the current (accepted) state, as the receptor
    recorder samples them."""
    from fingertip_dolfinx.post import CauchyStress, DerivedFields, PointSampler

    derived = DerivedFields(problem.u, problem.fmesh.cell_tags, problem.region_energies())
    derived.update()
    laws = {problem.tags[n]: law for n, law in problem.laws.regions.items()}
    stress = CauchyStress(problem.u, problem.fmesh.cell_tags, laws,
                          problem.options.quadrature_degree)
    stress.update()
    sample = PointSampler(problem.mesh, points)
    p = PointSampler(problem.submesh, points)(problem.p)[:, 0]
    return {"sed": sample(derived.sed)[:, 0],
            "compressive_strain": -sample(derived.principal)[:, 1],
            "compressive_stress": -(sample(stress.stress)[:, 3] - p)}


def test_site_transfer_at_two_hertz_is_the_instantaneous_change(pressed, vanishing_steps):
    """Serial (the samples are gathered on rank 0). The transfer functions to the stimulus
    quantities at points in the subcutaneous tissue
    under the bar (where sed, −e_min and −σ22 − p all respond): Re of the 2 Hz transfer equals
    the central difference of the quantities over one vanishing step to d ± δ, to 1 %: the
    exact derivatives, the pore pressure and the QLV split δσ = Dσ|_{S0} + (G* − g∞) F DS_e Fᵀ/J
    agree with the nonlinear model."""
    from fingertip_dolfinx.frequency_response import SiteTransfer

    problem, solver = pressed
    points = np.array([[0.0, problem.y_touch + 2.0], [0.3, problem.y_touch + 2.5]])
    transfer = SiteTransfer(problem, points)(solver.solve(2.0))
    depth, delta = problem.indentation(problem.time), 1e-4
    values = vanishing_steps(problem, (depth + delta, depth - delta),
                             lambda: _sampled_quantities(problem, points), "transfer_check_")
    for q, v in transfer.items():
        difference = (values[0][q] - values[1][q]) / (2 * delta)
        assert v.real == pytest.approx(difference, rel=1e-2), q


@pytest.mark.mpi
def test_run_writes_the_frequency_route(shared_tmp_path, capsys):
    """`fingertip run vibrotactile --frequencies ...`: the tables, the summary, the figures."""
    import csv
    import json

    from fingertip_dolfinx.cli import main

    out = shared_tmp_path / "vib"
    args = ["run", "vibrotactile", "--frequencies", "10,100,250", "--out", str(out), "--quiet",
            *(f"--set={o}" for o in COARSE)]
    assert main(args) == 0
    rows = list(csv.DictReader((out / "frequency_response.csv").open()))
    assert [float(r["frequency_Hz"]) for r in rows] == [10.0, 100.0, 250.0]
    for r in rows:  # |Z| = |K|/ω
        f = float(r["frequency_Hz"])
        assert float(r["Z_abs_Ns_per_mm2"]) == pytest.approx(
            float(r["K_abs_N_per_mm2"]) / (2 * math.pi * f), rel=1e-9)
    sites = list(csv.DictReader((out / "receptor_transfer.csv").open()))
    assert len(sites) % 3 == 0 and {s["class"] for s in sites} == {"SA1", "RA", "PC"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pressed_state"]["kind"] == "held" and summary["dofs"] > 0
    _check_resonances(summary, rows, capsys.readouterr().err)  # the console line: stderr
    assert (out / "impedance.png").exists() and (out / "receptor_transfer_PC.png").exists()
    _check_thresholds(out, sites)
    assert main(["run", "vibrotactile", "--frequencies", "0:1:3", "--out", str(out)]) == 2


def _check_resonances(summary, rows, printed: str):
    """summary.json names the resolved peaks and the unresolved ones' bands, and the console
    line says the same warning (3 frequencies resolve no peak: every sampled one is a band)."""
    from fingertip_dolfinx.frequency_response import resolution_warning, resonances

    found = resonances([{k: float(v) for k, v in r.items()} for r in rows])
    assert summary["resonances_Hz"] == {k: found[k] for k in ("probe_held", "force_driven")}
    assert summary["resonances_unresolved"] == found["unresolved"]
    assert summary["resonance_warning"] == resolution_warning(found)
    if MPI.COMM_WORLD.rank == 0 and summary["resonance_warning"]:
        assert summary["resonance_warning"] in printed


def _check_thresholds(out, sites):
    """thresholds.csv comes from the route's own transfer functions: its |H| is the class's
    quantity in receptor_transfer.csv at the same site and frequency, and I0·|H| (the
    threshold at the site, in the quantity's units) is the same at every site for the classes
    whose neuron does not read the pressed value (RA, PC: rate and acceleration weights only),
    since the probe threshold scales exactly as 1/|H| (vibrotactile.py)."""
    import csv
    import json

    from fingertip_dolfinx.afferents.receptors import receptors_from_dict

    # the set the run used (the scene's: "calibrated", whose SA1 reads −σ22, not SED)
    population = receptors_from_dict(json.loads((out / "receptors.json").read_text()))
    rows = list(csv.DictReader((out / "thresholds.csv").open()))
    assert len(rows) == len(sites) and (out / "thresholds.png").exists()
    pressed = list(csv.DictReader((out / "receptors.csv").open()))
    assert len(pressed) == len(sites) // 3  # the pressed state, one row per site
    transfer = {(s["class"], s["index"], s["frequency_Hz"]): s for s in sites}
    at_site = {}
    for r in rows:
        quantity = population[r["class"]].quantity
        h = float(transfer[r["class"], r["index"], r["frequency_Hz"]][f"{quantity}_abs_per_um"])
        assert float(r["H_abs_per_um"]) == pytest.approx(h, rel=1e-9)
        if r["class"] in ("RA", "PC") and r["I0_um"]:
            at_site.setdefault((r["class"], r["frequency_Hz"]), []).append(
                float(r["I0_um"]) * h)
    assert at_site
    for values in at_site.values():
        assert max(values) == pytest.approx(min(values), rel=1e-9)


def _oscillator_rows(frequencies, zeta: float, pole: bool) -> list[dict]:
    """frequency_response rows of a damped oscillator, f_n = 47 Hz: K = k − mω² + icω (a
    zero of K: |K| minimum, force driven) or, with `pole`, k²/K (a |K| maximum, probe held)."""
    k, fn = 1.0, 47.0
    rows = []
    for f in frequencies:
        r = f / fn
        K = k * (1 - r**2 + 2j * zeta * r)
        rows.append({"frequency_Hz": float(f), "K_abs_N_per_mm2": abs(k**2 / K if pole else K)})
    return rows


@pytest.mark.parametrize("pole", [True, False])
def test_resonance_reported_only_where_the_grid_resolves_it(pole):
    """The oscillator's peak is at f* = f_n √(1 − 2ζ²) (|K|² extreme). A 10-point log grid over
    1–1000 Hz has a sampled maximum at 46.4 Hz whose neighbours (21.5, 100 Hz) are far outside
    the 1.9 Hz half-power band: no frequency, a warning naming the band to refine. A 0.25 Hz
    grid resolves it: the reported frequency is within half a spacing of f* (where the best
    sample already is; the parabola through three samples does not do worse)."""
    from fingertip_dolfinx.frequency_response import resolution_warning, resonances

    kind = "probe_held" if pole else "force_driven"
    zeta = 0.02
    exact = 47.0 * math.sqrt(1 - 2 * zeta**2)
    coarse = resonances(_oscillator_rows(np.geomspace(1.0, 1000.0, 10), zeta, pole))
    assert coarse["probe_held"] == coarse["force_driven"] == []
    (unresolved,) = coarse["unresolved"]
    assert unresolved["kind"] == kind
    assert unresolved["refine_Hz"] == pytest.approx([1000 ** (4 / 9), 100.0])
    assert resolution_warning(coarse) == "not resolved by the grid: refine near 21.5–100 Hz"
    fine = resonances(_oscillator_rows(np.linspace(30.0, 70.0, 161), zeta, pole))
    (found,) = fine[kind]
    assert found == pytest.approx(exact, abs=0.25 / 2)
    assert fine["unresolved"] == [] and resolution_warning(fine) == ""


def test_a_peak_sharper_than_the_grid_is_reported_when_bracketed_closely():
    """ζ = 1e-4 (half-power band 0.01 Hz): no grid of 0.5 % steps resolves its width, but its
    neighbours bracket it within ±RESONANCE_PRECISION: reported, within one spacing of f*."""
    from fingertip_dolfinx.frequency_response import RESONANCE_PRECISION, resonances

    f = np.geomspace(40.0, 55.0, 60)
    assert f[2] / f[0] < (1 + RESONANCE_PRECISION) / (1 - RESONANCE_PRECISION)
    (found,) = resonances(_oscillator_rows(f, 1e-4, pole=True))["probe_held"]
    assert found == pytest.approx(47.0, abs=f[1] - f[0])


def test_the_impedance_axis_has_the_unit_of_the_runs_force(tmp_path, monkeypatch):
    """Z = δf/(iω δd) is a force per mm/s: N·s/mm per mm of thickness in plane strain, N·s/mm
    in 3D, where vibrotactile-3d's half model carries half the finger's force: its axis says
    so (`force_unit`'s names of the force)."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.frequency_response import plot_impedance

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    rows = [{**r, "Z_abs_Ns_per_mm2": r["K_abs_N_per_mm2"] / (2 * math.pi * r["frequency_Hz"]),
             "Z_phase_deg": -90.0} for r in _oscillator_rows(np.geomspace(10, 100, 5), 0.1, False)]
    for force, label in (("N/mm", "|Z| (N·s/mm per mm)"), ("N", "|Z| (N·s/mm)"),
                         ("N (half model)", "|Z| of the half model (N·s/mm)")):
        plot_impedance(rows, tmp_path / "impedance.png", force=force)
        assert drawn[-1].axes[0].get_ylabel() == label


def test_a_class_with_no_transfer_is_drawn_blank_not_a_failure(tmp_path, monkeypatch):
    """A class whose quantity has no first-order change anywhere (amplitude 0 at every site
    and frequency) has nothing to colour on a log scale: its figure says so, without a colour
    bar, and the others (and the route's remaining figures) are still drawn."""
    from types import SimpleNamespace

    from matplotlib.figure import Figure

    from fingertip_dolfinx.frequency_response import TRANSFER_COLUMNS, plot_receptor_transfer

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    rows = [{**dict.fromkeys(TRANSFER_COLUMNS, 0.0), "frequency_Hz": f, "class": cls,
             "x_mm": x, "depth_mm": 1.0, "sed_abs_per_um": (cls == "SA1") * f * (1 + x**2)}
            for f in (10.0, 100.0) for cls in ("SA1", "RA") for x in (-1.0, 0.0, 1.0)]
    population = {cls: SimpleNamespace(quantity="sed") for cls in ("SA1", "RA")}
    paths = plot_receptor_transfer(rows, tmp_path, population)
    assert [p.name for p in paths] == ["receptor_transfer_SA1.png", "receptor_transfer_RA.png"]
    assert [len(fig.axes) for fig in drawn] == [2, 1]  # the colour bar: SA1's only
    assert "zero" in drawn[1].axes[0].texts[0].get_text()


def test_a_3d_population_keeps_the_sites_of_largest_peak_response():
    """The 3D thresholds are searched on the `most` sites whose |H| peaks highest over the
    sweep (the most sensitive afferent among them); all sites when `most` is None or more."""
    from fingertip_dolfinx.frequency_response import responsive_sites

    h = np.array([[1.0, 5.0, 2.0, 0.1], [3.0, 1.0, -2.5j, 0.2]])  # peaks 3, 5, 2.5, 0.2
    assert responsive_sites(h, 2).tolist() == [0, 1]
    assert responsive_sites(h, 3).tolist() == [0, 1, 2]
    assert responsive_sites(h, None).tolist() == responsive_sites(h, 9).tolist() == [0, 1, 2, 3]


def test_the_response_columns_carry_the_units_of_the_run(tmp_path):
    """frequency_response.csv names |K| and |Z| by their units: N/mm per mm and N·s/mm per mm
    in plane strain (force per unit thickness), N/mm and N·s/mm in 3D (a force): a 3D file
    whose header said per mm² would mislabel every value in it. The row holds the response's
    values under those names, and FrequencyResult reads Z back from either file."""
    from types import SimpleNamespace

    from fingertip_dolfinx.frequency_response import response_columns, response_row
    from fingertip_dolfinx.outputs import CsvLog
    from fingertip_dolfinx.result import FrequencyResult

    K, f = 3.0 - 4.0j, 100.0
    r = SimpleNamespace(frequency=f, stiffness=K, impedance=K / (2j * math.pi * f),
                        wall_time_s=0.1)
    for unit, suffix in (("N/mm", "_per_mm2"), ("N", "_per_mm"), ("N (half model)", "_per_mm")):
        columns = response_columns(unit)
        assert {"K_abs_N" + suffix, "Z_abs_Ns" + suffix} <= set(columns)
        row = response_row(r, columns)
        assert row["K_abs_N" + suffix] == 5.0 and row["K_real"] == 3.0
        assert row["Z_abs_Ns" + suffix] == pytest.approx(5.0 / (2 * math.pi * f), rel=1e-15)
        out = tmp_path / unit.replace("/", "_per_").replace(" ", "_")
        out.mkdir()
        log = CsvLog(out / "frequency_response.csv", columns, MPI.COMM_SELF)
        log.write([row])
        log.close()
        assert FrequencyResult(out).impedance[0] == pytest.approx(r.impedance, rel=1e-9)
