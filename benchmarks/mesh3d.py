"""Benchmark: the 3D fingertip mesh at the tests' coarse size and at the built-in
file's sizes, full and half model. Prints cells, vertices, gmsh quality (minSICN) and edge
lengths, the wall time of geometry + meshing on rank 0 (MeshReport.seconds) and of the whole
build (with the distribution), and the region volumes' errors against the closed forms.

    .venv/bin/python benchmarks/mesh3d.py
"""

import time

from mpi4py import MPI

from fingertip_dolfinx.geometry.fingertip3d import load_fingertip3d
from fingertip_dolfinx.geometry.mesh3d import build_mesh3d, report_dict3d

CASES = {
    "coarse (tests), h = 1.6": {"mesh": {"min_size": 1.6, "max_size": 1.6, "bone_size": 3.2}},
    "h = 0.8": {"mesh": {"min_size": 0.8, "max_size": 0.8, "bone_size": 1.6}},
    "male-index-3d (0.4 / 1.0 / 2.0)": {},
}


def main():
    for half in (False, True):
        for label, overrides in CASES.items():
            tip = load_fingertip3d(overrides={**overrides, "half": half})
            start = time.perf_counter()
            fm = build_mesh3d(tip, MPI.COMM_WORLD)
            wall = time.perf_counter() - start
            report = report_dict3d(fm, tip)
            r = fm.report
            errors = ", ".join(f"{name} {v['relative_error']:+.1e}"
                               for name, v in report["volumes_mm3"].items())
            if MPI.COMM_WORLD.rank == 0:
                print(f"{'half' if half else 'full'} {label}: {r.num_cells} tetrahedra, "
                      f"{r.num_vertices} vertices, minSICN min {r.min_quality:.3f} mean "
                      f"{r.mean_quality:.3f}, edges {r.min_edge:.3f}-{r.max_edge:.3f} mm; gmsh "
                      f"{r.seconds:.1f} s, build {wall:.1f} s; volume errors: {errors}")


if __name__ == "__main__":
    main()
