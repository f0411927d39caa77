"""`fingertip run SCENE --check` and `ft.check(scene)`: a scene checked in seconds, without
running it. Every table is validated and every file it names found (loading the scene does
both), the output folder must be writable, and a 2D scene's mesh is built (under a second)
so that an indenter that would never reach the skin is named before a run is started. A 3D
mesh takes minutes: it is not built, and the report says so.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from dolfinx.mesh import entities_to_geometry
from mpi4py import MPI

from .errors import InputError
from .geometry.fingertip3d import Fingertip3D
from .geometry.mesh import build_mesh
from .problem import first_touch
from .runner import check_reach
from .scene import Scene, blamed, load_scene


def check(scene: Scene | str | Path, out: str | Path | None = None,
          overrides: Mapping | Sequence[str] = (), spacing: float | None = None,
          comm: MPI.Comm = MPI.COMM_WORLD) -> list[str]:
    """Check a scene and its output folder in seconds, without running it.

    Every table is validated, every file the scene names found, `out` tested for writing (nothing
    is created) and, for a 2D scene, the mesh built to check that every indenter reaches the
    skin (a 3D mesh takes minutes: it is not built, and the report says so).

    Parameters
    ----------
    scene : Scene or str or Path
        A scene, or a scene name or file (read with `overrides` and `spacing` as `load_scene`
        reads them).
    out : str or Path or None, optional
        The output folder to check; None: not checked.
    overrides : mapping or sequence of str, optional
        As for `load_scene` (with a scene name or file only).
    spacing : float or None, optional
        As for `load_scene`.
    comm : MPI.Comm, optional
        The communicator the mesh is built on.

    Returns
    -------
    list of str
        The report's lines (what was checked and found).

    Raises
    ------
    InputError
        The first mistake found.
    """
    start = time.perf_counter()
    if not isinstance(scene, Scene):
        scene = load_scene(scene, overrides, spacing=spacing)
    lines = [f"{scene.title}: every table valid; files found: {_files(scene)}"]
    if out is not None:
        lines.append(writable(Path(out)))
    try:
        lines.append(_mesh_and_reach(scene, comm))
    except InputError as error:
        raise blamed(scene, error) from None
    lines.append(f"check passed in {time.perf_counter() - start:.1f} s")
    return lines


def _files(scene: Scene) -> str:
    receptors = f", receptors {scene.outputs.receptors}" if scene.outputs.receptors else ""
    shapes = ", ".join(i.shape for i in scene.indenters)
    return (f"section {scene.section.name}, indenters {shapes}, materials "
            f"{scene.materials.name}{receptors}")


def writable(out: Path, label: str = "--out") -> str:
    """`out` can be made (or is) a folder this process can write into: a file can be created
    in it or in the folder it would be made in (tried, then removed: root ignores modes)."""
    if out.exists() and not out.is_dir():
        raise InputError(f"{label} {out}", "is a file, not a folder.", "give a folder.")
    folder = out
    while not folder.exists():
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{label} {out}", f"cannot be made: {folder} is a file.",
                         "give a folder whose parents are folders.")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as error:
        raise InputError(f"{label} {out}", f"no file can be written in {folder} "
                         f"({error.strerror}).", "give a folder you can write to.") from None
    # the folder by its full name: a relative `out` whose parents do not exist yet is made in
    # the working folder, which a bare "." would not name
    return f"{out}: writable" + ("" if out.exists() else f" (to be made in {folder.resolve()})")


def _mesh_and_reach(scene: Scene, comm: MPI.Comm) -> str:
    """Build a 2D scene's mesh and check that every indenter reaches the skin (the run's own
    test, `runner.check_reach`, on the mesh's pulp vertices); a 3D one is skipped."""
    if isinstance(scene.section, Fingertip3D):
        return (f"mesh: not built (3D, minutes; `fingertip mesh --section "
                f"{scene.section.name}` builds it); whether the indenters reach the skin is "
                "checked at the start of the run")
    start = time.perf_counter()
    fmesh = build_mesh(scene.section, comm)
    seconds = time.perf_counter() - start
    mesh = fmesh.mesh
    facets = fmesh.facet_tags.find(fmesh.names["pulp_surface"])
    nodes = entities_to_geometry(mesh, mesh.topology.dim - 1, facets)
    X = mesh.geometry.x[np.unique(nodes), :2]
    points = np.concatenate(comm.allgather(X))
    stand_in = SimpleNamespace(pulp_nodes=lambda: (X, X), mesh=mesh, mirror_factor=1,
                               y_touch=first_touch(points, scene.indenters))
    check_reach(stand_in, scene)
    return (f"mesh: {fmesh.report.num_cells} {fmesh.report.cell_type}s built in {seconds:.1f} s; "
            f"every indenter reaches the skin by {scene.history.deepest:g} mm")

