r"""Small-signal frequency response about a pressed state: the frequency-domain route.

About a converged state x0 = (u0, p0) the residual is linearised and a harmonic drive
δd e^{iωt} (the indenter's vertical displacement) gives x = x0 + Re(δx e^{iωt}) with

    [K + Σ_v G*_v(ω) K_v + iω B − ω² M] δx = b δd,                              (1)

every matrix real and assembled once:

- K: the ω-independent tangent: the Jacobians of the elastic regions' stresses, the QLV
  region's geometric term ∫ (Grad δu S0) : Grad v dX with S0 = g∞ S_e0 + Σ g_i h_i the frozen
  total PK2 (its internal variables as stored at the state), the pore pressure's coupling
  −∫ p J F⁻ᵀ : Grad v, the contact's Jacobian (the Nitsche pressure's kink frozen at the state:
  the contact set does not change over a cycle; the drive must stay below the depth) and the
  Darcy flux ∫ J k(J) C⁻¹ Grad p · Grad q dX linearised in both u and p (incl. the frozen
  Grad p0);
- K_v: per viscoelastic (QLV) law, its material tangent ∫ (F0 DS_e[δu]) : Grad v dX, times the
  Prony complex modulus G*(ω) = g∞ + Σ g_i iωτ_i/(1 + iωτ_i) (the Fourier transform of
  h_i = ∫ e^{−(t−s)/τ_i} dS_e(s): δh_i = iωτ_i/(1 + iωτ_i) δS_e);
- B: the biphasic mass balance's rate term ∫ DJ[δu] q dX (per unit time: iω δJ + Darcy flux;
  the fluid moves with the solid: the relative fluid's acceleration and the fluid's own
  inertia beyond the mixture density are neglected, as in the quasi-static model);
- M: the mass ∫ ρ δu·v dX of the deformable regions (the reference densities, ρ0 = J ρ).
  An undrained pore law has no rate: its ∫ DJ[δu] q dX = 0 sits in K.

The drive: the contact residual depends on the indenter only through x + u − (tip position),
and on Grad u; every other part on Grad u alone. So R(u + c e_y; d + c) = R(u; d) and
∂R/∂d = −K_contact e_y with e_y the uniform vertical field: b = K_contact e_y (checked against
a finite difference of the residual in tests/test_harmonic.py). The indenter force f (the
contact residual tested with e_y) linearises the same way: δf = Df[δu − e_y δd].

The PETSc build is real, so (1), A x = b with A = A_r + i A_i, is solved in real block form

    [[A_r, −A_i], [A_i, A_r]] [x_r; x_i] = [b_r; b_i],

one MUMPS LU per frequency (one AIJ matrix built from the blocks' CSR arrays, the same
pattern at every ω). Every matrix is assembled into a copy of K's sparsity (each of their
forms has a subset of K's couplings), so A_r and A_i are sums by `axpy` with the same
pattern. (Adding 0 × K's forms to each would give the pattern too, but compiles the whole
tangent again per matrix: in 3D 4.5 MB of C and minutes of compiler each.) Dirichlet rows:
K carries the unit diagonal, the other matrices zero rows, the drive
zero entries (the clamp does not move).

Outputs per ω (`Response`): δx (real and imaginary parts), δf per unit δd, the dynamic stiffness
K(ω) = δf/δd and the driving-point impedance Z(ω) = δf/(iω δd): N/mm per mm and N·s/mm per mm
in plane strain, N/mm and N·s/mm in 3D.

The pressed state (`press`): "held" steps the scene's pre-indentation (ramp and hold) and
freezes the state at its end; "relaxed" is the model's own long-term equilibrium at the depth:
the ramp, then steps far longer than every relaxation time (Δt ≫ τ_i and the consolidation
time; `relaxation_time`): h_i → 0 so S = g∞ S_e, and the pore pressure becomes uniform — not
zero: the subcutaneous boundary is impermeable, the tissue's volume is conserved, and the
long-term limit is the drained solid under that one volume constraint (each huge
backward-Euler step tests the mass balance with q = 1: ∫ J − J_n dX = 0 exactly).
"""

from __future__ import annotations

import math
import time as wallclock
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import dolfinx.fem.petsc as fpetsc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from .errors import InputError
from .harmonic_options import STATES
from .loading import RampHold
from .physics.materials import Prony
from .physics.poroelasticity import consolidation_time, darcy_flux
from .stepping.controllers import BACKWARD_EULER
from .stepping.options import StepOptions
from .stepping.stepper import TimeStepper

#: The LU solve of the real block form.
HARMONIC_PETSC_OPTIONS = {"ksp_type": "preonly", "pc_type": "lu",
                          "pc_factor_mat_solver_type": "mumps",
                          # Past the resonances the operator is indefinite: MUMPS delays pivots
                          # and its default workspace estimate (+20 %) failed at 1000 Hz on the
                          # coarse fingertip (KSP_DIVERGED_PC_FAILED).
                          "mat_mumps_icntl_14": 100}
#: "relaxed": steps of RELAXATION_FACTOR × the longest relaxation time (`relaxation_steps`).
RELAXATION_FACTOR = 100.0


def complex_modulus(prony: Prony | None, omega: float) -> complex:
    """G*(ω) = g∞ + Σ g_i iωτ_i/(1 + iωτ_i): g∞ at ω = 0, 1 (instantaneous) as ω → ∞."""
    if prony is None:
        return 1.0 + 0.0j
    return prony.g_inf + sum(g * 1j * omega * tau / (1 + 1j * omega * tau)
                             for g, tau in zip(prony.g, prony.tau))


# --- the linearisation as data --------------------------------------------------------------


@dataclass
class ViscousPart:
    """A viscoelastic law's material tangent (block bilinear forms) and its Prony series."""

    blocks: list
    prony: Prony


@dataclass
class Linearisation:
    """The real forms of (1) about a state. Block forms are lists of lists over the unknowns
    (None: no block); `drive` and `force` are linear forms per unknown (None: zero):
    b = drive (the load of a unit drive, −∂R/∂d) and δf = force·δx + force_drive δd."""

    unknowns: list
    K: list
    M: list
    B: list
    viscous: list = field(default_factory=list)
    drive: list = field(default_factory=list)
    force: list = field(default_factory=list)
    force_drive: ufl.Form | float = 0.0
    bcs: list = field(default_factory=list)
    entity_maps: list | None = None


def qlv_tangent(qlv, F, u, du, v, dx) -> tuple[ufl.Form, ufl.Form]:
    """(geometric, material) parts of a QLV law's tangent on `dx`: ∫ (Grad δu S0) : Grad v with
    S0 = g∞ S_e + Σ g_i h_i (the stored history), and ∫ (F DS_e[δu]) : Grad v."""
    prony = qlv.prony
    S0 = prony.g_inf * qlv.S_e + sum(g * h for g, h in zip(prony.g, qlv.h))
    geometric = ufl.inner(ufl.grad(du) * S0, ufl.grad(v)) * dx
    material = ufl.inner(F * ufl.derivative(qlv.S_e, u, du), ufl.grad(v)) * dx
    return geometric, material


def uniform_field(V, component: int = 1) -> fem.Function:
    """The uniform unit vector field e_component in the vector space V (e_y by default)."""
    e = fem.Function(V)
    e.x.array.reshape(-1, V.dofmap.index_map_bs)[:, component] = 1.0
    return e


def linearise(problem) -> Linearisation:
    """The linearisation (1) of a `problem.FingertipProblem` about its current state, driven
    by the indenters' common vertical displacement."""
    u, V, F = problem.u, problem.V, problem.F
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    tags, dx = problem.tags, problem.dx
    rho = problem.tissues.densities()
    K_uu, M_uu, viscous = 0, 0, []
    for name, law in problem.laws.regions.items():
        d = dx(tags[name])
        if law.history is None:
            K_uu += ufl.derivative(ufl.inner(law.stress, ufl.grad(v)) * d, u, du)
        else:
            geometric, material = qlv_tangent(law.history, F, u, du, v, d)
            K_uu += geometric
            viscous.append((material, law.history.prony))
        if not law.rigid:
            M_uu += rho[name] * ufl.inner(du, v) * d
    contact = problem.contact.residual(v)
    K_uu += ufl.derivative(contact, u, du)
    e_y = uniform_field(V)
    force = -problem.contact.residual(e_y)  # the indenters' y-force on the body
    lin = Linearisation(
        unknowns=list(problem.unknowns), K=[[K_uu]], M=[[M_uu]], B=[[None]],
        viscous=[ViscousPart([[m]], prony) for m, prony in viscous],
        drive=[ufl.derivative(contact, u, e_y)], force=[ufl.derivative(force, u, v)],
        force_drive=-ufl.derivative(force, u, e_y), bcs=list(problem.bcs),
        entity_maps=problem.entity_maps)
    if problem.p is not None:
        _add_pressure(lin, problem, u, du, v)
    return lin


def _add_pressure(lin: Linearisation, problem, u, du, v) -> None:
    """The pore pressure's blocks: coupling (u rows), flux and rate (p rows)."""
    p = problem.p
    Q = p.function_space
    q, dp = ufl.TestFunction(Q), ufl.TrialFunction(Q)
    dx_sub = problem.dx(problem.tags["subcutaneous"])
    coupling = problem.pressure_coupling
    lin.K[0][0] += ufl.derivative(coupling, u, du)
    volume = ufl.det(problem.F) * q * dx_sub
    pore = problem.laws.pore
    if pore.has_rate:  # Darcy flow: ∫ iω δJ q + D(flux)[δu, δp]
        flux = darcy_flux(u, p, q, pore.material) * dx_sub
        K_pu = ufl.derivative(flux, u, du)
        K_pp = ufl.derivative(flux, p, dp)
        B_pu = ufl.derivative(volume, u, du)
    else:  # undrained: δJ = 0, no rate
        K_pu, K_pp, B_pu = ufl.derivative(volume, u, du), None, None
    lin.K = [[lin.K[0][0], ufl.derivative(coupling, p, dp)], [K_pu, K_pp]]
    lin.M = [[lin.M[0][0], None], [None, None]]
    lin.B = [[None, None], [B_pu, None]]
    for part in lin.viscous:
        part.blocks = [[part.blocks[0][0], None], [None, None]]
    lin.drive = [*lin.drive, None]
    lin.force = [*lin.force, None]


# --- the solve ------------------------------------------------------------------------------


@dataclass
class Response:
    """The response to a unit drive at one frequency: δx = x_r + i x_i per unknown (owned and
    ghost entries, the unknowns' layout) and the force δf (N/mm per mm of drive)."""

    frequency: float
    x_r: list
    x_i: list
    force: complex
    wall_time_s: float = math.nan

    @property
    def omega(self) -> float:
        return 2 * math.pi * self.frequency

    @property
    def stiffness(self) -> complex:
        """K(ω) = δf/δd (N/mm per mm in plane strain, N/mm in 3D)."""
        return self.force

    @property
    def impedance(self) -> complex:
        """Z(ω) = δf/(iω δd): the driving-point mechanical impedance (N·s/mm per mm in plane
        strain, N·s/mm in 3D)."""
        return self.force / (1j * self.omega)

    def displacement(self, unknown: int = 0) -> np.ndarray:
        """δx of one unknown as complex values (owned and ghost entries)."""
        return self.x_r[unknown] + 1j * self.x_i[unknown]


class HarmonicSolver:
    """Assembles the matrices of a `Linearisation` once and solves (1) per frequency."""

    def __init__(self, lin: Linearisation, petsc_options: dict | None = None,
                 prefix: str = "harmonic_"):
        self.lin = lin
        self.comm = lin.unknowns[0].function_space.mesh.comm
        started = wallclock.perf_counter()
        self._mesh = lin.unknowns[0].function_space.mesh
        self.K = self._matrix(lin.K, 1.0)
        self.M = self._matrix(lin.M, 0.0, like=self.K)
        self.B = self._matrix(lin.B, 0.0, like=self.K)
        self.viscous = [(self._matrix(v.blocks, 0.0, like=self.K), v.prony)
                        for v in lin.viscous]
        spaces = [f.function_space for f in lin.unknowns]
        self.b = self._vector(lin.drive, spaces, bcs=True)
        self.g = self._vector(lin.force, spaces, bcs=False)
        fd = lin.force_drive
        self.force_drive = (self.comm.allreduce(fem.assemble_scalar(self._form(fd)), op=MPI.SUM)
                            if isinstance(fd, ufl.Form) else float(fd))
        self.spaces = spaces
        self.options = {**HARMONIC_PETSC_OPTIONS, **(petsc_options or {})}
        self.prefix = prefix
        self._A = self._ksp = None
        self.assembly_time_s = wallclock.perf_counter() - started

    # assembly
    def _form(self, form):
        return fem.form(form, entity_maps=self.lin.entity_maps)

    def _matrix(self, blocks, diag: float, like: PETSc.Mat | None = None) -> PETSc.Mat:
        """The blocks' matrix; with `like`, assembled into a zeroed copy of its pattern (a
        block of no form, None, stays zero)."""
        if like is None:
            A = fpetsc.assemble_matrix(self._form(blocks), bcs=self.lin.bcs, diag=diag,
                                       kind="mpi")
        else:
            A = like.duplicate(copy=False)
            A.zeroEntries()
            if any(form is not None for row in blocks for form in row):
                fpetsc.assemble_matrix(A, self._form(_spanning(blocks, self.lin.K, self._mesh)),
                                       bcs=self.lin.bcs, diag=diag)
        A.assemble()
        return A

    def _vector(self, forms, spaces, bcs: bool) -> PETSc.Vec:
        filled = [f if f is not None else _zero_form(s) for f, s in zip(forms, spaces)]
        compiled = self._form(filled)
        vec = fpetsc.assemble_vector(compiled, kind="mpi")
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        if bcs:
            fpetsc.set_bc(vec, _bcs_by_block(spaces, self.lin.bcs))
        return vec

    # the complex operator in real block form
    def operator(self, omega: float) -> tuple[PETSc.Mat, PETSc.Mat]:
        """(A_r, A_i) of (1) at ω."""
        same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        A_r = self.K.copy()
        A_r.axpy(-omega**2, self.M, same)
        A_i = self.B.copy()
        A_i.scale(omega)
        for K_v, prony in self.viscous:
            G = complex_modulus(prony, omega)
            A_r.axpy(G.real, K_v, same)
            A_i.axpy(G.imag, K_v, same)
        return A_r, A_i

    def _block_matrix(self, omega: float) -> PETSc.Mat:
        """[[A_r, −A_i], [A_i, A_r]] as one AIJ matrix whose rows on each rank are its rows of
        A_r then the same rows of A_i (so the vectors are [x_r owned; x_i owned] per rank).
        Built from the CSR arrays (a MatNest converted to AIJ keeps references to the nest:
        destroying it broke the solve)."""
        A_r, A_i = self.operator(omega)
        indptr, cols, a_r = A_r.getValuesCSR()
        indptr_i, cols_i, a_i = A_i.getValuesCSR()
        if not (np.array_equal(indptr, indptr_i) and np.array_equal(cols, cols_i)):
            raise RuntimeError("A_r and A_i do not share their sparsity pattern.")
        A_r.destroy()
        A_i.destroy()
        counts = np.diff(indptr)
        first = np.repeat(indptr[:-1], counts) + np.arange(len(cols))  # entry k of row r
        second = first + np.repeat(counts, counts)  # at 2 ip[r] + (k − ip[r]) (+ count)
        real_cols, imag_cols = self._split_columns(cols, self.K.getOwnershipRanges())
        big_cols = np.empty(2 * len(cols), dtype=PETSc.IntType)
        big_cols[first], big_cols[second] = real_cols, imag_cols
        top, bottom = np.empty(2 * len(cols)), np.empty(2 * len(cols))
        top[first], top[second] = a_r, -a_i
        bottom[first], bottom[second] = a_i, a_r
        big_indptr = np.concatenate([2 * indptr, 2 * indptr[-1] + 2 * indptr[1:]])
        csr = (big_indptr.astype(PETSc.IntType), np.concatenate([big_cols, big_cols]),
               np.concatenate([top, bottom]))
        n, N = self.K.getSizes()[0]
        if self._A is None:
            self._A = PETSc.Mat().createAIJ(((2 * n, 2 * N), (2 * n, 2 * N)), csr=csr,
                                            comm=self.comm)
        else:
            self._A.setValuesCSR(*csr)
        self._A.assemble()
        return self._A

    @staticmethod
    def _split_columns(cols: np.ndarray, ranges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Global column j of the complex system -> its columns in the real block form: rank s
        owning j (rows o_s .. o_s + n_s) holds 2 o_s + (j − o_s) (real) and + n_s (imaginary)."""
        owner = np.searchsorted(ranges, cols, side="right") - 1
        start, size = ranges[owner], np.diff(ranges)[owner]
        real = start + cols
        return real, real + size

    def _solver(self, A: PETSc.Mat) -> PETSc.KSP:
        if self._ksp is None:
            ksp = PETSc.KSP().create(self.comm)
            ksp.setOptionsPrefix(self.prefix)
            opts = PETSc.Options()
            for key, value in self.options.items():
                opts[f"{self.prefix}{key}"] = value
            ksp.setFromOptions()
            self._ksp = ksp
        self._ksp.setOperators(A)
        return self._ksp

    def solve(self, frequency: float) -> Response:
        """The response to a unit drive at `frequency` (Hz)."""
        if not (frequency > 0 and math.isfinite(frequency)):
            raise InputError("harmonic.frequencies", f"got {frequency!r} Hz.",
                             "use positive frequencies (Hz).")
        started = wallclock.perf_counter()
        omega = 2 * math.pi * frequency
        A = self._block_matrix(omega)
        ksp = self._solver(A)
        n = self.b.getLocalSize()
        rhs, sol = A.createVecs()
        rhs.array[:n] = self.b.array_r
        rhs.array[n:] = 0.0
        ksp.solve(rhs, sol)
        reason = ksp.getConvergedReason()
        if reason < 0:
            info = ksp.getPC().getFactorMatrix().getMumpsInfog(1)
            raise RuntimeError(f"the harmonic solve at {frequency:g} Hz failed (KSP reason "
                               f"{reason}, MUMPS INFOG(1) = {info}): is the pressed state "
                               "supported and in contact?")
        parts = []
        for half in (sol.array_r[:n], sol.array_r[n:]):
            vec = self.b.duplicate()
            vec.array[:] = half
            parts.append(vec)
        force = complex(self.g.dot(parts[0]), self.g.dot(parts[1])) + self.force_drive
        x_r, x_i = (self._unknown_arrays(vec) for vec in parts)
        for m in (rhs, sol, *parts):
            m.destroy()
        return Response(frequency, x_r, x_i, force, wallclock.perf_counter() - started)

    def _unknown_arrays(self, vec: PETSc.Vec) -> list[np.ndarray]:
        functions = [fem.Function(V) for V in self.spaces]
        fpetsc.assign(vec, functions)
        for f in functions:
            f.x.scatter_forward()
        return [f.x.array.copy() for f in functions]

    def sweep(self, frequencies: Sequence[float],
              on_frequency: Callable[[Response], None] | None = None) -> list[Response]:
        """Solve at every frequency in order; `on_frequency` after each."""
        responses = []
        for f in frequencies:
            responses.append(self.solve(f))
            if on_frequency is not None:
                on_frequency(responses[-1])
        return responses

    def close(self) -> None:
        """Destroy the PETSc objects on every rank together (MUMPS frees collectively)."""
        for obj in (self._ksp, self._A, self.K, self.M, self.B, self.b, self.g,
                    *(m for m, _ in self.viscous)):
            if obj is not None:
                obj.destroy()


def _bcs_by_block(spaces, bcs) -> list[list]:
    """The Dirichlet conditions on each space (fem.bcs_by_block trips over the C++ space of a
    DirichletBC in DOLFINx 0.11)."""
    return [[bc for bc in bcs if V._cpp_object.contains(bc.function_space)] for V in spaces]


def _zero_form(V) -> ufl.Form:
    """A linear form that is identically zero on V (keeps a block's place)."""
    msh = V.mesh
    v = ufl.TestFunction(V)
    zero = fem.Constant(msh, 0.0)
    value = zero * v[0] if len(v.ufl_shape) else zero * v
    return value * ufl.dx(domain=msh)


def _spanning(blocks: list, pattern: list, msh) -> list:
    """`blocks` with a zero form wherever the block assembler needs one: each empty diagonal
    block (it needs one where Dirichlet rows are) gets 0 × a mass-like form of its spaces,
    cheap to compile and within the tangent's pattern; a row or column still empty, 0 × the
    `pattern` form there (the pore pressure's couplings when the flux block is absent)."""
    out = [list(row) for row in blocks]
    n = len(out)
    zero = fem.Constant(msh, 0.0)  # a Constant: UFL would fold a literal 0 away
    for i in range(n):
        if out[i][i] is None and pattern[i][i] is not None:
            test, trial = pattern[i][i].arguments()
            domain = test.ufl_function_space().mesh
            out[i][i] = zero * ufl.inner(trial, test) * ufl.dx(domain=domain)
    for i in range(n):
        for j in range(n):
            empty = all(f is None for f in out[i]) or all(r[j] is None for r in out)
            if empty and out[i][j] is None and pattern[i][j] is not None:
                out[i][j] = zero * pattern[i][j]
    return out


# --- the pressed state ----------------------------------------------------------------------


def relaxation_time(problem) -> float:
    """The longest time scale of the model's relaxation (s): the largest Prony τ_i and the
    subcutaneous tissue's consolidation time over the section's size (its drainage path:
    poroelasticity.consolidation_time)."""
    times = [max(law.history.prony.tau) for law in problem.laws.with_history()]
    pore = problem.laws.pore
    material = getattr(pore, "material", None)
    if material is not None:
        X = problem.mesh.geometry.x  # (n, 3); z = 0 in 2D
        local = float(np.ptp(X, axis=0).max()) if len(X) else 0.0
        size = problem.mesh.comm.allreduce(local, op=MPI.MAX)
        times.append(consolidation_time(material, size))
    return max(times, default=1.0)


@dataclass
class PressedState:
    """The state the response is linearised about, and how it was reached."""

    kind: str
    depth: float
    force: float
    time: float
    steps: int
    wall_time_s: float

    def record(self) -> dict:
        return dict(self.__dict__)


def press(problem, pressing: RampHold, kind: str = "relaxed", steps: StepOptions | None = None,
          petsc_options: dict | None = None,
          on_step: Callable | None = None, linear: str = "direct") -> PressedState:
    """Bring `problem` to its pressed state (see the module's docstring) and leave it there:
    "held" steps `pressing` (ramp and hold) to its end; "relaxed" steps its ramp, then holds the
    depth
    with the `relaxation_steps`. The problem's `history` is replaced by the one it was pressed
    with (the state then stays at its depth whatever `set_time` is given). `linear` is the
    linear solver inside Newton (the scene's `[solver] linear`: "direct" or "iterative")."""
    if kind not in STATES:
        raise InputError("harmonic.state", f"unknown pressed state {kind!r}.",
                         f"use one of {STATES}.")
    started = wallclock.perf_counter()
    problem.history = pressing
    stepper = TimeStepper(problem, steps, petsc_options, linear=linear)
    try:
        end = pressing.end_time if kind == "held" else pressing.ramp_time
        reports = stepper.run(pressing, end, on_step=on_step)
        if kind == "relaxed":
            reports += _relax(problem, stepper, pressing, on_step)
    finally:
        stepper.close()
    return PressedState(kind, float(pressing.depth), float(np.sum(problem.contact.forces())),
                        problem.time, len(reports), wallclock.perf_counter() - started)


def _relax(problem, stepper: TimeStepper, pressing: RampHold, on_step) -> list:
    """Hold the depth with the `relaxation_steps` (the stepper may cut them if Newton fails)."""
    dts = relaxation_steps(problem)
    start = pressing.ramp_time
    hold = RampHold(pressing.depth, pressing.ramp_time, start + sum(dts))
    problem.history = hold
    stepper.options = StepOptions(dt_initial=dts[0], dt_min=1e-3 * dts[0], dt_max=dts[-1],
                                  growth=dts[1] / dts[0], extrapolate=False)
    return stepper.run(hold, hold.end_time, start_time=start, on_step=on_step)


def step_force(problem, depth: float, dts: Sequence[float]) -> float:
    """The indenter force (N/mm) after backward-Euler steps of lengths `dts` from the current
    (accepted) state to the indentation `depth` (all at that depth); the state is restored
    afterwards. One step of dt → 0: the instantaneous (undrained, unrelaxed) response; steps
    ≫ `relaxation_time` (`relaxation_steps`): the long-term one. For checks of the limits."""
    stepper = TimeStepper(problem, StepOptions(), prefix="fingertip_step_")
    saved = {name: array.copy() for name, array in problem.state_arrays().items()}
    saved_time, dt_before = problem.time, float(problem.dt.value)
    try:
        problem.rate_weights.value[:] = BACKWARD_EULER
        for obstacle in problem.obstacles:
            obstacle.y_tip.value = problem.y_touch + depth
        for dt in dts:
            problem.dt.value = dt
            reason, _ = stepper.solve_once()
            if reason <= 0:
                raise RuntimeError(f"the step to {depth:g} mm over {dt:g} s did not converge "
                                   f"(SNES reason {reason}).")
            force = float(np.sum(problem.contact.forces()))
            problem.accept()
    finally:
        stepper.close()
        for name, array in problem.state_arrays().items():
            array[:] = saved[name]
        for f in problem.unknowns:
            f.x.scatter_forward()
        problem.mark_accepted()
        problem.dt.value = dt_before
        problem.set_time(saved_time)
    return force


def relaxation_steps(problem) -> tuple[float, ...]:
    """Step lengths (s) that relax the model fully: RELAXATION_FACTOR × `relaxation_time`,
    then ten times that, twice. Each backward-Euler step leaves ~τ/Δt of what remains to relax
    (1e-2, then 1e-3 twice: 1e-8 in all); longer single steps lose Newton's convergence to the
    round-off of the huge Darcy terms (Δt k ~ 1e10 on the paper's tissue)."""
    T = RELAXATION_FACTOR * relaxation_time(problem)
    return (T, 10 * T, 10 * T)
