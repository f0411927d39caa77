"""fingertip-dolfinx: finite-strain biomechanics of touch in FEniCSx.

A plane-strain fingertip (skin, subcutaneous tissue, bone, nail) pressed by rigid indenters,
after Wu et al. (2004). The modules follow the physics, each depending only on those before it:
geometry -> mesh -> kinematics -> materials -> tissues -> contact -> model -> problem ->
stepping -> scene -> runner -> outputs / figures -> studies.

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

from importlib import import_module

# The PyPI wheel's PETSc must be set up before dolfinx or petsc4py is imported. Python runs
# this file before any module of the package (`import fingertip_dolfinx.mesh` imports the
# package first), so no module needs to import the package root for it.
try:
    import dolfinx_solver  # noqa: F401
except ImportError:  # DOLFINx from conda or the official images needs no set-up.
    pass

#: Public name -> the module that defines it.
_API = {
    # scenes: experiments as data, and running them
    "Scene": "scene", "Outputs": "scene", "load_scene": "scene",
    "run": "routes", "route_of": "routes", "run_scene": "runner", "check": "checks",
    "Result": "result", "FrequencyResult": "result", "load_result": "result",
    "adapt": "adaptivity", "AdaptOptions": "adaptivity",
    # materials as data
    "Tissues": "tissues", "Rigid": "tissues", "load_materials": "tissues", "WU2004": "tissues",
    "Hyperfoam": "materials", "Prony": "materials", "HolmesMow": "materials",
    "ConstantPermeability": "materials", "Biphasic": "materials", "LinearElastic": "materials",
    # geometry, mesh, indenters, protocols
    "Section": "geometry", "MeshOptions": "geometry", "load_section": "geometry",
    "build_mesh": "mesh",
    "Fingertip3D": "geometry3d", "load_fingertip3d": "geometry3d", "build_mesh3d": "mesh3d",
    "Wedge": "indenters", "Bar": "indenters", "Cylinder": "indenters", "Plate": "indenters",
    "load_indenter": "indenters",
    "RampHold": "loading", "PiecewiseLinear": "loading", "Sinusoid": "loading",
    "Vibration": "loading",
    # the model, the problem and the solver, for those who build their own runs
    "ModelOptions": "model", "FingertipProblem": "problem",
    "StepOptions": "stepping", "TimeStepper": "stepping",
    # receptor sites and afferent models
    "load_receptors": "receptors", "ReceptorPopulation": "receptors",
    "afferent_responses": "receptors",
    # errors
    "FingertipError": "errors", "InputError": "errors", "ConvergenceError": "errors",
    "CompactionError": "errors", "RunInterrupted": "errors",
}
__all__ = sorted(_API)


def _version() -> str:
    """The version pyproject.toml gives (its one place): the installed distribution's, or in
    a source tree that is not installed, read from the tree's pyproject.toml."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fingertip-dolfinx")
    except PackageNotFoundError:
        import tomllib
        from pathlib import Path

        try:
            with (Path(__file__).resolve().parents[1] / "pyproject.toml").open("rb") as f:
                return tomllib.load(f)["project"]["version"]
        except (OSError, KeyError, tomllib.TOMLDecodeError):
            return "0+unknown"


def __getattr__(name: str):
    if name == "__version__":  # read on first use: `import fingertip_dolfinx` stays fast
        globals()[name] = _version()
        return globals()[name]
    if name not in _API:
        raise AttributeError(f"module 'fingertip_dolfinx' has no attribute {name!r}")
    value = getattr(import_module(f".{_API[name]}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
