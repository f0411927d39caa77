"""The vibrating layer: a viscoelastic hyperfoam layer on a rigid base, laterally confined, its top
shaken harmonically: the standing wave of uniaxial strain in closed form (`driven_layer`,
`driven_layer_force`), the exact check of the frequency-domain route (`harmonic`: G*(ω), the
mass, the real block form)."""

from __future__ import annotations

import math

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from ...harmonic import Linearisation, ViscousPart, complex_modulus, qlv_tangent
from ...physics import materials as mat
from ...physics.kinematics import deformation_gradient
from ...physics.viscoelasticity import QuasiLinearViscoelasticity
from .block import confined_modulus
from .wiring import QUADRATURE_DEGREE


def driven_layer(y, H: float, omega: float, density: float, modulus: complex) -> np.ndarray:
    r"""u(y)/U of a uniform layer 0 ≤ y ≤ H held at y = 0 and displaced U e^{iωt} at y = H,
    laterally confined (a one-dimensional P-wave), in the steady state:

        M* u'' + ρ ω² u = 0,  u(0) = 0, u(H) = U  ⇒  u(y) = U sin(k y)/sin(k H),

    k = ω sqrt(ρ/M*), M* the complex confined modulus (M0 G*(ω) for a QLV solid). Complex:
    the amplitude and phase relative to the drive (either root k: the ratio is even in k)."""
    k = omega * np.sqrt(density / complex(modulus))
    return np.sin(k * np.asarray(y, dtype=float)) / np.sin(k * H)


def driven_layer_force(H: float, omega: float, density: float, modulus: complex) -> complex:
    """The top traction σ_yy(H)/U = M* k cos(kH)/sin(kH) (MPa/mm) of `driven_layer`: the force
    per unit width that holds the driven top, per unit drive amplitude."""
    k = omega * np.sqrt(density / complex(modulus))
    return complex(modulus) * k * np.cos(k * H) / np.sin(k * H)


class VibratingLayer:
    """A QLV hyperfoam layer [0, W] × [0, H] on a rigid base (u = 0 at y = 0), on rollers
    (u_x = 0 on the sides: uniaxial strain), its top loaded by a uniform harmonic traction;
    linearised at rest (C = I) for `harmonic.HarmonicSolver`.

    Exact: ρ (iω)² u = M* u'' with M*(ω) = M0 G*(ω), M0 = K0 + 4μ0/3 the hyperfoam's confined
    modulus at C = I (`confined_modulus`) and G* the Prony complex modulus; u(0) = 0 gives
    u(y) = U sin(k y)/sin(k H), k = ω sqrt(ρ/M*), and the traction the top needs per unit top
    displacement is the dynamic stiffness M* k cot(k H) (MPa/mm). The layer is driven by a unit
    traction and its output is the mean top displacement, so the computed stiffness is
    1/output (the same operator as a displacement drive; a traction drive keeps the drive a
    right-hand side, as the fingertip's is).
    """

    def __init__(self, solid, prony, density: float, *, H: float = 5.0, width: float = 0.25,
                 cells: int = 40, degree: int = 2, comm=MPI.COMM_SELF):
        self.solid, self.prony, self.rho, self.H, self.W = solid, prony, density, H, width
        self.msh = mesh.create_rectangle(comm, [[0.0, 0.0], [width, H]], [1, cells])
        V = fem.functionspace(self.msh, ("Lagrange", degree, (2,)))
        self.V, self.u = V, fem.Function(V)
        self.qlv = QuasiLinearViscoelasticity(
            mat.second_piola_kirchhoff(solid, deformation_gradient(self.u)), prony, self.msh,
            QUADRATURE_DEGREE, 1.0)

    def _bcs(self) -> list:
        V, fdim = self.V, 1
        base = mesh.locate_entities_boundary(self.msh, fdim, lambda x: np.isclose(x[1], 0.0))
        sides = mesh.locate_entities_boundary(
            self.msh, fdim, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], self.W))
        side_dofs = fem.locate_dofs_topological(V.sub(0), fdim, sides)
        return [fem.dirichletbc(np.zeros(2), fem.locate_dofs_topological(V, fdim, base), V),
                fem.dirichletbc(0.0, side_dofs, V.sub(0))]

    def linearisation(self) -> Linearisation:
        u, V = self.u, self.V
        v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
        dx = ufl.dx(metadata=self.qlv.metadata)
        geometric, material = qlv_tangent(self.qlv, deformation_gradient(u), u, du, v, dx)
        top = mesh.locate_entities_boundary(self.msh, 1, lambda x: np.isclose(x[1], self.H))
        tags = mesh.meshtags(self.msh, 1, top, np.ones_like(top))
        ds = ufl.Measure("ds", domain=self.msh, subdomain_data=tags)(1)
        return Linearisation(
            unknowns=[u], K=[[geometric]], M=[[self.rho * ufl.inner(du, v) * dx]], B=[[None]],
            viscous=[ViscousPart([[material]], self.prony)], drive=[v[1] * ds],
            force=[v[1] / self.W * ds], bcs=self._bcs())

    def modulus(self, frequency: float) -> complex:
        """M*(ω) = M0 G*(ω), the complex confined modulus (MPa)."""
        omega = 2 * math.pi * frequency
        return confined_modulus(self.solid) * complex_modulus(self.prony, omega)

    def exact_stiffness(self, frequency: float) -> complex:
        """M* k cot(k H): the top traction per unit top displacement (MPa/mm)."""
        return driven_layer_force(self.H, 2 * math.pi * frequency, self.rho,
                                  self.modulus(frequency))

    def exact_profile(self, y: np.ndarray, frequency: float) -> np.ndarray:
        """u_y(y) per unit top displacement: sin(k y)/sin(k H)."""
        return driven_layer(y, self.H, 2 * math.pi * frequency, self.rho, self.modulus(frequency))
