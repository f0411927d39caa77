"""fingertip-dolfinx: finite-strain biomechanics of touch in FEniCSx.

The chain of modules follows the physics, each depending only on those before it:
geometry -> mesh -> kinematics -> materials -> tissues -> contact -> model -> problem -> solver
-> scene -> post.
"""

try:  # The PyPI wheel's PETSc must be set up before dolfinx or petsc4py is imported.
    import dolfinx_solver  # noqa: F401
except ImportError:  # DOLFINx from conda or the official images needs no set-up.
    pass

__version__ = "0.1.0"
