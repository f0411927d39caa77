"""fingertip-dolfinx: finite-strain biomechanics of touch in FEniCSx.

A plane-strain fingertip (skin, subcutaneous tissue, bone, nail) pressed by rigid indenters,
after Wu et al. (2004). The subpackages follow the physics (geometry, physics, stepping,
afferents, plotting, studies); each module depends only on those before it in the chain of
docs/DESIGN.md, which a test checks.

The Python API, in the order a study uses it::

    import fingertip_dolfinx as ft

    scene = ft.load_scene("line-load", {"materials": {"subcutaneous": {"permeability":
                                                                       {"k0": 1e-2}}}})
    ft.check(scene)                                # validated, files found, mesh built
    result = ft.run(scene, "results/k0-1e-2")
    result.time, result.force                      # the history, as arrays
    x, sed = result.depth_profile("sed_MPa", depth=0.75, t=1.0)

or from parts, without a scene file::

    scene = ft.Scene(section=ft.load_section("male-index"),
                     indenters=[ft.Bar(width=1.0)],
                     history=ft.RampHold(depth=1.0, ramp_time=1.0, end_time=1.0),
                     materials=ft.load_materials("wu2004", {"bone": {"model": "rigid"}}))

The names below are imported on first use, so that `import fingertip_dolfinx` (and the
`fingertip --help` command) stays fast.
"""

from .lazy import lazy_exports

# The PyPI wheel's PETSc must be set up before dolfinx or petsc4py is imported. Python runs
# this file before any module of the package (`import fingertip_dolfinx.geometry.mesh` imports
# the package first), so no module needs to import the package root for it.
try:
    import dolfinx_solver  # noqa: F401
except ImportError:  # DOLFINx from conda or the official images needs no set-up.
    pass

#: The public names, by the module that defines them (imported on first use).
_MODULES = {
    # scenes: experiments as data, and running them
    "scene": ("Scene", "Outputs", "load_scene"),
    "routes": ("run", "route_of"),
    "runner": ("run_scene",),
    "checks": ("check",),
    "result": ("Result", "FrequencyResult", "load_result"),
    "studies.adaptivity": ("adapt", "AdaptOptions"),
    # materials as data
    "physics.tissues": ("Tissues", "Rigid", "load_materials", "WU2004"),
    "physics.materials": ("Hyperfoam", "Prony", "HolmesMow", "ConstantPermeability", "Biphasic",
                          "LinearElastic"),
    # geometry, mesh, indenters, protocols
    "geometry.section": ("Section", "MeshOptions", "load_section"),
    "geometry.mesh": ("build_mesh",),
    "geometry.fingertip3d": ("Fingertip3D", "load_fingertip3d"),
    "geometry.mesh3d": ("build_mesh3d",),
    "geometry.indenters": ("Wedge", "Bar", "Cylinder", "Plate", "load_indenter"),
    "loading": ("RampHold", "PiecewiseLinear", "Sinusoid", "Vibration"),
    # the model, the problem and the solver, for those who build their own runs
    "model": ("ModelOptions",),
    "problem": ("FingertipProblem",),
    "stepping": ("StepOptions", "TimeStepper"),
    # receptor sites and afferent models
    "afferents.receptors": ("load_receptors", "ReceptorPopulation", "afferent_responses"),
    # errors
    "errors": ("FingertipError", "InputError", "ConvergenceError", "CompactionError",
               "RunInterrupted"),
}
#: Public name -> the module that defines it.
_API = {name: module for module, names in _MODULES.items() for name in names}
__all__ = sorted(_API)


_exported, __dir__ = lazy_exports(__name__, _API)


def __getattr__(name: str):
    if name == "__version__":  # read on first use: `import fingertip_dolfinx` stays fast
        from .datafiles import package_version

        globals()[name] = package_version()
        return globals()[name]
    return _exported(name)
