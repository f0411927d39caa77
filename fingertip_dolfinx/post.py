"""Post-processing: derived fields, point sampling that is exact in parallel, result files.

Derived fields (logarithmic strain, principal log strains, strain energy density) are
interpolated into discontinuous P1 spaces by expressions compiled once; curves are sampled
with `determine_point_ownership`, which gives every point to exactly one rank, so serial and
parallel runs write the same rows.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem, geometry
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .kinematics import hencky_strain, principal_log_strains

#: The columns of the result files (stable names: other tools read them).
HISTORY_COLUMNS = ("time_s", "indenter_displacement_mm", "force_N_per_mm", "newton_iterations",
                   "dt_s", "reaction_N_per_mm", "max_penetration_mm", "min_J", "cuts",
                   "wall_time_s")
SURFACE_COLUMNS = ("x_mm", "time_s", "deflection_mm")
DEPTH_COLUMNS = ("x_mm", "depth_mm", "time_s", "u1_mm", "u2_mm", "e11", "e22", "e12", "e_max",
                 "e_min", "sed_MPa", "p_MPa")


class PointSampler:
    """Evaluates functions of one mesh at fixed points; results gathered on rank 0.

    `points` (n, 2) must be the same on every rank. Points outside the mesh give NaN.
    """

    def __init__(self, msh: dmesh.Mesh, points: np.ndarray, padding: float = 1e-10):
        self.comm = msh.comm
        self.n = len(points)
        mine = np.zeros((self.n if self.comm.rank == 0 else 0, 3))
        if self.comm.rank == 0:
            mine[:, :2] = points
        data = geometry.determine_point_ownership(msh, mine, padding)
        self._points = np.asarray(data.dest_points).reshape(-1, 3)
        self._cells = np.asarray(data.dest_cells, dtype=np.int32)
        # On rank 0: which rank evaluates each point (-1: outside the mesh). A rank receives
        # its points in the order rank 0 sent them.
        self._owner = np.asarray(data.src_owner) if self.comm.rank == 0 else None

    def __call__(self, f: fem.Function) -> np.ndarray | None:
        """Values (n, value size) on rank 0, None on the other ranks."""
        size = f.function_space.dofmap.index_map_bs
        shape = f.function_space.value_shape
        size = int(np.prod(shape)) if shape else 1
        values = (f.eval(self._points, self._cells).reshape(-1, size) if len(self._cells)
                  else np.zeros((0, size)))
        gathered = self.comm.gather(values, root=0)
        if self.comm.rank != 0:
            return None
        out = np.full((self.n, size), np.nan)
        for rank, vals in enumerate(gathered):
            out[np.flatnonzero(self._owner == rank)] = vals
        return out


class DerivedFields:
    """Log strain, principal log strains and strain energy density as DG1 functions.

    `energies` maps a cell-tag value to the UFL strain energy density of that region.
    """

    def __init__(self, u: fem.Function, cell_tags: dmesh.MeshTags, energies: dict[int, object]):
        msh = u.function_space.mesh
        F = ufl.Identity(2) + ufl.grad(u)
        tensor = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (2, 2)))
        vector = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (2,)))
        scalar = fem.functionspace(msh, ("Discontinuous Lagrange", 1))
        self.log_strain = fem.Function(tensor, name="log_strain")
        self.principal = fem.Function(vector, name="principal_log_strain")
        self.sed = fem.Function(scalar, name="strain_energy_density")
        self._sed_by_region = []
        self._plan = [
            (self.log_strain, fem.Expression(hencky_strain(F), tensor.element.interpolation_points)),
            (self.principal, fem.Expression(ufl.as_vector(principal_log_strains(F)),
                                            vector.element.interpolation_points)),
        ]
        for tag, energy in energies.items():
            cells = cell_tags.find(tag)
            self._sed_by_region.append(
                (cells, fem.Expression(energy, scalar.element.interpolation_points))
            )

    def update(self) -> None:
        for f, expr in self._plan:
            f.interpolate(expr)
        for cells, expr in self._sed_by_region:
            self.sed.interpolate(expr, cells0=cells)
        for f in (self.log_strain, self.principal, self.sed):
            f.x.scatter_forward()


def depth_curve(outer, depth: float, half_width: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points at `depth` below the palmar outer ellipse, along its inward normals.

    Returns (x of the surface points the normals start from, the points (n, 2)).
    """
    x = np.linspace(-half_width, half_width, n)
    a, b, cy = outer.a, outer.b, outer.cy
    y = cy - b * np.sqrt(np.clip(1 - (x / a) ** 2, 0.0, None))
    normal = np.column_stack([x / a**2, (y - cy) / b**2])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return x, np.column_stack([x, y]) - depth * normal


class CsvLog:
    """A CSV file written row by row on rank 0 (flushed, so a crash loses nothing)."""

    def __init__(self, path: Path, columns: Sequence[str], comm: MPI.Comm, resume_after=None):
        self.comm, self.columns, self.path = comm, tuple(columns), path
        self._file = None
        if comm.rank != 0:
            return
        rows = []
        if resume_after is not None and path.exists():
            # Keep the rows up to the checkpoint; later ones are recomputed.
            with path.open() as f:
                rows = [r for r in csv.DictReader(f) if float(r["time_s"]) <= resume_after + 1e-12]
        self._file = path.open("w", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns)
        self._writer.writeheader()
        for r in rows:
            self._writer.writerow(r)
        self._file.flush()

    def write(self, rows: Sequence[dict]) -> None:
        if self._file is None:
            return
        for row in rows:
            self._writer.writerow({k: _fmt(row.get(k)) for k in self.columns})
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()


def _fmt(value):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float | np.floating):
        return f"{value:.12g}"
    return value


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a result CSV as float arrays (empty cells become NaN)."""
    with Path(path).open() as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    return {k: np.array([float(r[k]) if r[k] != "" else np.nan for r in rows]) for k in rows[0]}


def write_json(path: Path, data: dict, comm: MPI.Comm) -> None:
    if comm.rank == 0:
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")
        tmp.replace(path)  # atomic: readers never see half a file


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {value!r}")
