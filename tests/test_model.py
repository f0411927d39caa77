"""The seams of the model: region laws composed from the materials and options, the pressure
unknown per pore model, rigid regions from the materials file, the admissibility checks, and
what the recorder reads (state_arrays, region_energies).

The laws are checked at a homogeneous deformation against numpy closed forms (principal
Kirchhoff stresses of the hyperfoam, St Venant–Kirchhoff, Hooke), not against the UFL they
are built from.
"""

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.mesh import create_unit_square
from mpi4py import MPI

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.model import (
    BiphasicFlow,
    Elastic,
    ModelOptions,
    RigidRegion,
    SmallStrain,
    State,
    Undrained,
    Viscoelastic,
    compose_laws,
)
from fingertip_dolfinx.physics.admissibility import Admissibility, Compaction
from fingertip_dolfinx.physics.tissues import REGIONS, WU2004, load_materials, tissues_from_dict
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import DEFAULT_PETSC_OPTIONS, TimeStepper

COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0"]
#: A homogeneous stretch (diagonal: principal stretches λ1, λ2, λ3 = 1) and a sheared state.
STRETCH = np.diag([1.1, 0.85])
SHEAR = np.array([[1.02, 0.03], [0.01, 0.99]])
QLV_STATES = {"qlv_h0", "qlv_h1", "qlv_S_e_n"}


# --- laws at a homogeneous state on a unit square ---------------------------------------------


def _state(F0: np.ndarray, dt: float = 0.5) -> State:
    msh = create_unit_square(MPI.COMM_SELF, 2, 2)
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 1, (2,))))
    u.interpolate(lambda x: (F0 - np.eye(2)) @ x[:2])
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    F = fem.Constant(msh, F0)  # exact F; SmallStrain reads Grad u, which is exact for linear u
    return State(u, F, fem.Constant(msh, dt), 4, dict.fromkeys(REGIONS, cells))


def _value(expr, state: State, points=((1 / 3, 1 / 3),)) -> np.ndarray:
    """The value of `expr` at the first of `points` of cell 0 (the state is homogeneous)."""
    values = fem.Expression(expr, np.array(points)).eval(state.mesh, np.array([0], np.int32))
    return values.reshape(len(points), -1)[0]


def _hyperfoam_P(material, F0):
    """P = diag(τ_a/λ_a) for a diagonal F (principal Kirchhoff stresses, plane strain)."""
    tau = material.principal_kirchhoff([F0[0, 0], F0[1, 1], 1.0])
    return np.diag(tau[:2] / np.diag(F0))


def _svk_P(material, F0):
    E = 0.5 * (F0.T @ F0 - np.eye(2))
    return F0 @ (material.lmbda * np.trace(E) * np.eye(2) + 2 * material.mu * E)


def test_layered_laws_are_the_materials_laws():
    state = _state(STRETCH)
    laws = compose_laws(WU2004, ModelOptions(skin_viscoelastic=False), state)
    skin, sub, bone, nail = (laws.regions[r] for r in REGIONS)
    assert all(type(law) is Elastic for law in (skin, sub, bone, nail))
    np.testing.assert_allclose(_value(skin.stress, state),
                               _hyperfoam_P(WU2004.skin, STRETCH).ravel(), rtol=1e-12)
    np.testing.assert_allclose(_value(sub.stress, state),
                               _hyperfoam_P(WU2004.subcutaneous.solid, STRETCH).ravel(), rtol=1e-12)
    for law, material in ((bone, WU2004.bone), (nail, WU2004.nail)):
        np.testing.assert_allclose(_value(law.stress, state), _svk_P(material, STRETCH).ravel(),
                                   rtol=1e-12)
    W = WU2004.skin.principal_energy([1.1, 0.85, 1.0])
    assert _value(skin.energy, state)[0] == pytest.approx(float(W), rel=1e-12)
    # The contact's stiffness scale: λ0 + 2μ0 of the skin = E(1 − ν)/((1 + ν)(1 − 2ν)).
    mu, nu = WU2004.skin.mu0, WU2004.skin.nu
    E = 2 * mu * (1 + nu)
    assert skin.p_wave_modulus == pytest.approx(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu)), rel=1e-14)


def test_viscoelastic_skin_relaxes_its_first_step_and_keeps_its_elastic_stress():
    """From a stress-free history, one step of Δt scales S_e by g∞ + Σ g_i (1 − a_i) τ_i/Δt,
    a_i = exp(−Δt/τ_i); the contact's estimate stays the instantaneous elastic stress."""
    dt = 0.5
    state = _state(STRETCH, dt)
    skin = compose_laws(WU2004, ModelOptions(), state).regions["skin"]
    assert type(skin) is Viscoelastic and skin.history is not None
    prony = WU2004.skin_prony
    a = np.exp(-dt / np.array(prony.tau))
    factor = prony.g_inf + np.sum(np.array(prony.g) * (1 - a) * np.array(prony.tau) / dt)
    P_e = _hyperfoam_P(WU2004.skin, STRETCH)
    points = skin.history.space.element.interpolation_points  # the history's own points
    np.testing.assert_allclose(_value(skin.stress, state, points), factor * P_e.ravel(),
                               rtol=1e-12)
    np.testing.assert_allclose(_value(skin.elastic_stress, state), P_e.ravel(), rtol=1e-12)


def test_continuum_is_one_small_strain_law_with_its_own_energy():
    """The continuum rung: σ = λ tr ε I + 2μ ε everywhere and W = ½ σ:ε in every region."""
    state = _state(SHEAR)
    options = ModelOptions(tissue="continuum")
    laws = compose_laws(WU2004, options, state)
    assert laws.pore is None and laws.rigid_regions() == ()
    law = laws.regions["skin"]
    assert type(law) is SmallStrain and all(laws.regions[r] is law for r in REGIONS)
    E, nu = options.continuum_E, options.continuum_nu
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = 0.5 * (SHEAR + SHEAR.T) - np.eye(2)
    sigma = lmbda * np.trace(eps) * np.eye(2) + 2 * mu * eps
    np.testing.assert_allclose(_value(law.stress, state), sigma.ravel(), rtol=1e-12)
    W = 0.5 * np.sum(sigma * eps)
    assert _value(law.energy, state)[0] == pytest.approx(W, rel=1e-12)
    # The layered laws are other laws: in the bone region (the old SED output's choice for the
    # continuum) the SVK energy of the 17 GPa bone is ~1e7 times the continuum's own.
    bone_W = _value(compose_laws(WU2004, ModelOptions(), state).regions["bone"].energy, state)[0]
    assert bone_W > 1e6 * W


@pytest.mark.parametrize(("subcutaneous", "pore"), [("biphasic", BiphasicFlow),
                                                   ("undrained", Undrained), ("drained", None)])
def test_pore_law_per_subcutaneous_model(subcutaneous, pore):
    laws = compose_laws(WU2004, ModelOptions(subcutaneous=subcutaneous), _state(STRETCH))
    assert (laws.pore is None) if pore is None else (type(laws.pore) is pore)
    if pore is not None:
        assert laws.pore.phi0 == WU2004.subcutaneous.phi0


def test_rigid_regions_from_the_materials_or_the_option():
    state = _state(STRETCH)
    bone_rigid = load_materials("wu2004", {"bone": {"model": "rigid"}})
    laws = compose_laws(bone_rigid, ModelOptions(), state)
    assert laws.rigid_regions() == ("bone",) and type(laws.regions["nail"]) is Elastic
    assert _value(laws.regions["bone"].stress, state) == pytest.approx(np.zeros(4), abs=0)
    laws = compose_laws(WU2004, ModelOptions(rigid_bone=True), state)
    assert laws.rigid_regions() == ("bone", "nail")
    assert all(type(laws.regions[r]) is RigidRegion for r in ("bone", "nail"))


# --- admissibility --------------------------------------------------------------------------


@pytest.mark.parametrize(("F0", "message"), [
    (np.diag([1.0, -0.5]), "inverted elements (J = -0.5) at a "),
    (np.diag([1.0, 0.41]), ("compaction: the tissue's volume ratio J reached 0.41 at a ")),
    (np.diag([1.0, 0.43]), None),
])
def test_admissibility_messages(F0, message):
    state = _state(F0)
    F = ufl.Identity(2) + ufl.grad(state.u)
    cells = state.cells["subcutaneous"]
    check = Admissibility(F, state.mesh, 4, Compaction(cells, 0.4, 0.02))
    assert check.min_jacobian()[0] == pytest.approx(np.linalg.det(F0), rel=1e-12)
    why = check.violation()
    assert why is None if message is None else why.startswith(message), why


# --- the problem on the fingertip ------------------------------------------------------------


@pytest.fixture(scope="module")
def scene():
    return load_scene("1pt", COARSE)


@pytest.fixture(scope="module")
def fmesh(scene):
    return build_mesh(scene.section)


def _problem(scene, fmesh, tissues=WU2004, **options):
    return FingertipProblem(fmesh, scene.indenters, scene.history, tissues,
                            ModelOptions(**options))


def test_a_problem_waits_for_a_form_another_process_compiles(scene, fmesh, monkeypatch):
    # Runs side by side (one per rank) compile the same output forms at once on a cold cache:
    # with FFCx's 10 s wait one rank gave up and sat in a collective until the other's runs
    # ended. Every form a problem's run compiles (2D or 3D, Newton or output) waits longer.
    from dolfinx import jit

    defaults = dict(jit.DOLFINX_DEFAULT_JIT_OPTIONS)
    monkeypatch.setattr(jit, "DOLFINX_DEFAULT_JIT_OPTIONS", defaults)
    defaults["timeout"] = (10, "Timeout for JIT compilation")  # FFCx's own default
    _problem(scene, fmesh, subcutaneous="drained")
    assert jit.get_options()["timeout"] >= 600, "a compile can take minutes: wait >= 10 min"


@pytest.mark.parametrize(("options", "keys"), [
    ({}, {"u", "u_n", "u_nm1", "p"} | QLV_STATES),  # u_nm1: the biphasic rate (BDF2)
    ({"subcutaneous": "undrained", "skin_viscoelastic": False}, {"u", "u_n", "p"}),
    ({"subcutaneous": "drained"}, {"u", "u_n"} | QLV_STATES),
    ({"tissue": "continuum"}, {"u", "u_n"}),
])
def test_pressure_unknown_and_state_arrays_per_option(scene, fmesh, options, keys):
    problem = _problem(scene, fmesh, **options)
    arrays = problem.state_arrays()
    assert set(arrays) == keys
    has_p = "p" in keys
    assert (problem.p is not None) == has_p
    assert len(problem.unknowns) == len(problem.residuals) == 1 + has_p
    assert (problem.qlv is not None) == ("qlv_h0" in keys)
    arrays["u"][:] = 0.25  # the live arrays: a checkpoint writes the state through them
    assert np.all(problem.u.x.array == 0.25)


def test_region_energies_are_each_regions_own(scene, fmesh):
    tags = fmesh.names
    problem = _problem(scene, fmesh, tissue="continuum")
    energies = problem.region_energies()
    assert set(energies) == {tags[r] for r in REGIONS}
    assert all(energies[tags[r]] is problem.laws.regions["skin"].energy for r in REGIONS)
    problem = _problem(scene, fmesh, rigid_bone=True)
    energies = problem.region_energies()
    assert isinstance(energies[tags["bone"]], fem.Constant)
    assert energies[tags["nail"]].value == 0.0


def _run(problem, scene) -> list:
    stepper = TimeStepper(problem, scene.steps, scene.petsc_options, prefix="test_model_")
    try:
        return stepper.run(scene.history, scene.history.end_time)
    finally:
        stepper.close()


def test_rigid_bone_from_the_materials_file_holds_the_body(scene, fmesh):
    """A rigid bone (materials data) is clamped node by node instead of the nail centre; the
    force the indenter puts in comes out at the clamped bone, step by step."""
    tissues = load_materials("wu2004", {"bone": {"model": "rigid"}})
    problem = _problem(scene, fmesh, tissues)
    bone = fmesh.cell_tags.find(fmesh.names["bone"])
    bone_dofs = fem.locate_dofs_topological(problem.V, 2, bone)
    assert np.array_equal(np.sort(problem.clamped_dofs), np.sort(bone_dofs))
    reports = _run(problem, scene)
    force = np.array([r.diagnostics["force_N_per_mm"] for r in reports])
    reaction = np.array([r.diagnostics["reaction_N_per_mm"] for r in reports])
    assert reports[-1].time == pytest.approx(scene.history.end_time)
    assert np.all(np.diff(force) > 0) and force[-1] > 0
    np.testing.assert_allclose(reaction, force, rtol=1e-8, atol=DEFAULT_PETSC_OPTIONS["snes_atol"])


def test_rigid_bone_and_nail_from_the_file_is_the_rigid_bone_option(scene, fmesh):
    both = load_materials("wu2004", {"bone": {"model": "rigid"}, "nail": {"model": "rigid"}})
    from_file = _run(_problem(scene, fmesh, both), scene)
    from_option = _run(_problem(scene, fmesh, rigid_bone=True), scene)
    forces = [[r.diagnostics["force_N_per_mm"] for r in run] for run in (from_file, from_option)]
    np.testing.assert_allclose(forces[0], forces[1], rtol=1e-14)


# --- densities (read by the dynamic analyses only) ---------------------------------------------


def test_densities_are_read_recorded_and_required_by_region():
    rho = WU2004.densities()
    assert rho == {"skin": 1.09e-9, "subcutaneous": 1.0e-9, "bone": 1.92e-9, "nail": 1.3e-9}
    assert load_materials("wu2004", WU2004.record()).densities() == rho  # the record reads back
    rigid = load_materials("wu2004", {"bone": {"model": "rigid"}})
    assert rigid.densities()["bone"] == 0.0  # a clamped region needs no density
    data = WU2004.record()
    del data["skin"]["density"]
    with pytest.raises(InputError, match=r"skin\.density.*add density = 1\.0e-9"):
        tissues_from_dict(data).densities()
    with pytest.raises(InputError, match=r"nail\.density: must be positive"):
        load_materials("wu2004", {"nail": {"density": 0.0}})


@pytest.mark.parametrize("options, where", [
    ({"quadrature_degree": 1}, "model.quadrature_degree"),  # P2 stiffness is degree 2
    ({"quadrature_degree": 2.5}, "model.quadrature_degree"),
    ({"displacement_degree": 3, "quadrature_degree": 3}, "model.quadrature_degree"),
    ({"displacement_degree": 4}, "model.displacement_degree"),
    ({"tissue": "continuum", "continuum_nu": 0.5}, "model.continuum_E/continuum_nu"),
])
def test_options_refuse_what_cannot_be_computed(options, where):
    with pytest.raises(InputError, match=where.replace("/", ".")):
        ModelOptions(**options)


@pytest.mark.parametrize("k, q", [(1, 1), (2, 2), (3, 4)])
def test_options_accept_the_lowest_exact_stiffness_rule(k, q):
    assert ModelOptions(displacement_degree=k, quadrature_degree=q, subcutaneous="drained")
