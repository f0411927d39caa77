"""A run's fields as a pyvista grid (`Result.to_pyvista`): the mesh's own nodes and cells, the
arrays the run stored at them, the deformed grid at X + u; clear errors for a time that was
not an output time and for a run without stored fields."""

import re
import shutil

import numpy as np
import pytest
from mpi4py import MPI

import fingertip_dolfinx as ft
from fingertip_dolfinx.errors import InputError

#: The coarse one-point run of test_routes, with output times 0.5 and 1 s.
SETS = ["section.mesh.min_size=0.4", "section.mesh.max_size=1.5", "section.mesh.bone_size=2.0",
        "output.profile_points=21", "steps.dt_initial=0.5", "steps.dt_max=0.5",
        "output.pictures=false", "output.times=[0.5, 1.0]"]
#: The coarse probe-3d run of test_run3d.
SETS_3D = ["section.mesh.min_size=0.8", "section.mesh.max_size=2.0",
           "section.mesh.bone_size=3.0", "section.mesh.refine_z_min=1.0",
           "section.mesh.refine_z_max=6.0", "indenters.0.centre_z=3.0",
           "protocol.depth=0.3", "protocol.end_time=1.0", "output.times=[1.0]",
           "steps.dt_initial=0.25", "output.pictures=false"]
VTK_TRIANGLE, VTK_TETRA = 5, 10


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("result"), root=0)
    return ft.run("1pt", out, overrides=SETS, progress=False)


def _mesh_counts(out) -> tuple[int, int]:
    """(nodes, cells) of the run's mesh.xdmf, as written by DOLFINx."""
    text = (out / "mesh.xdmf").read_text()
    cells = int(re.search(r'NumberOfElements="(\d+)"', text).group(1))
    nodes = int(re.search(r'<Geometry[^>]*>\s*<DataItem Dimensions="(\d+) ', text).group(1))
    return nodes, cells


def _check_grid(result, t: float, cell_type: int):
    """The grid is the mesh, and its data are the run's arrays at the corners."""
    grid, f = result.to_pyvista(t), result.fields(t)
    nodes, cells = _mesh_counts(result.out)
    assert (grid.n_points, grid.n_cells) == (nodes, cells)
    corners = grid.cells_dict[cell_type]  # basix order = VTK order for simplices
    gdim = f["X"].shape[2]
    np.testing.assert_array_equal(grid.points[corners][..., :gdim], f["X"])
    np.testing.assert_array_equal(grid["displacement"][corners][..., :gdim], f["u"])
    np.testing.assert_array_equal(grid["region"], f["region"])
    np.testing.assert_allclose(grid["strain_energy_density"], f["sed"].mean(axis=1)[:, 0],
                               rtol=1e-14, atol=0)
    deformed = result.to_pyvista(t, warp=True)
    scale = np.abs(grid.points).max()
    np.testing.assert_allclose(deformed.points, grid.points + grid["displacement"],
                               rtol=0, atol=1e-14 * scale)
    return grid, f


def test_the_grid_is_the_mesh_with_the_runs_arrays(result):
    grid, f = _check_grid(result, 1.0, VTK_TRIANGLE)
    assert np.abs(grid["displacement"]).max() > 0.1  # pressed by 1 mm
    # the pore pressure at the subcutaneous corners; none elsewhere
    p = grid["pore_pressure"]
    at = {tuple(x): v for x, v in zip(grid.points[:, :2], p)}
    assert [at[tuple(x)] for x in f["X_p"].reshape(-1, 2)] == list(f["p"].ravel())
    subcutaneous = np.unique(grid.cells_dict[VTK_TRIANGLE][grid["region"] == 2])
    assert np.isnan(p).sum() == grid.n_points - len(subcutaneous)


def test_another_output_time_and_a_magnified_warp(result):
    half, full = result.to_pyvista(0.5), result.to_pyvista(1.0)
    assert np.abs(half["displacement"]).max() < np.abs(full["displacement"]).max()
    magnified = result.to_pyvista(1.0, warp=10)
    np.testing.assert_allclose(magnified.points, full.points + 10 * full["displacement"],
                               rtol=0, atol=1e-13)


def test_a_time_that_was_not_an_output_time_lists_them(result):
    with pytest.raises(InputError, match=r"not an output time.*\[0\.5, 1\.0\]"):
        result.to_pyvista(0.7)


def test_a_run_without_stored_fields_says_so(result, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(result.out, copy)
    (copy / "fields_t1s.npz").unlink()
    with pytest.raises(InputError, match="stored no field arrays"):
        ft.load_result(copy).to_pyvista(1.0)


@pytest.mark.slow
def test_a_3d_run_gives_a_tetrahedral_grid(tmp_path_factory):
    """probe-3d, coarse (3615 tetrahedra; minutes on a shared machine)."""
    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("probe3d"), root=0)
    result = ft.run("probe-3d", out, overrides=SETS_3D, progress=False)
    grid, _ = _check_grid(result, 1.0, VTK_TETRA)
    assert grid["log_strain"].shape == (grid.n_cells, 9)


@pytest.mark.parametrize("dim, column, unit", [(2, "force_N_per_mm", "N/mm"), (3, "force_N", "N")])
def test_force_reads_the_runs_own_column_and_unit(tmp_path, dim, column, unit):
    """A 3D run records forces in N (`force_N`), a plane-strain run in N/mm: `force` and the
    summary line must read the column the run wrote, not assume the plane-strain one."""
    (tmp_path / "history.csv").write_text(f"time_s,{column}\n0.5,1.5\n1.0,3.0\n")
    key = "peak_force_" + unit.replace("/", "_per_")
    (tmp_path / "summary.json").write_text(f'{{"scene": "s{dim}", "{key}": 3.0}}')
    result = ft.load_result(tmp_path)
    assert result.force_unit == unit
    np.testing.assert_array_equal(result.force, [1.5, 3.0])
    assert f"peak force 3.0 {unit}," in repr(result)
