"""Benchmark: the cost of each integral of the Newton forms (the Jacobian blocks and the
residual) of a scene, by region: CPU µs per cell of the generated kernel alone (called
through cffi on this rank's cells, the matrix insertion left out), the region's cells, the
kernel's lines of C, and the whole Jacobian's assembly (kernels + insertion) for comparison.

    .venv/bin/python benchmarks/jacobian_kernels.py                   # line-load-3d, 1 rank
    .venv/bin/mpiexec -n 2 .venv/bin/python benchmarks/jacobian_kernels.py --repeats 3
    .venv/bin/python benchmarks/jacobian_kernels.py --cflags="-O2 -g0" --cache-dir /tmp/O2

`--cflags` replaces the 3D forms' C compiler flags (problem.JIT_OPTIONS_3D), `--cache-dir` the
FFCx cache (an empty one: the cold compile's time, printed with the table).

The state is `fingertip_3d.smooth_state`'s (strains of a few per cent); a kernel's cost does
not depend on the state's branch (FFCx evaluates both sides of every conditional), only on
the transcendental functions' arguments, a little.
"""

import os
import re
import time

import numpy as np
from fingertip_3d import smooth_state
from mpi4py import MPI
from timing import scene_and_out, scene_parser, tally

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.problem import JIT_OPTIONS_3D


def main():
    parser = scene_parser(__doc__, "line-load-3d")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cflags", default=None, help="C compiler flags of the 3D forms")
    parser.add_argument("--cache-dir", default=None, help="FFCx cache of the 3D forms")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    _jit_options(args.cflags, args.cache_dir)
    import dolfinx.jit

    compiling = tally(dolfinx.jit, "ffcx_jit")
    scene, out = scene_and_out(args, comm)
    job = smooth_state(scene, out, comm)
    nonlinear = job.stepper.nonlinear
    names = {v: k for k, v in job.problem.tags.items()}
    rows = []
    for label, form in _forms(nonlinear):
        rows += [(label, *row) for row in _integrals(form, names, args.repeats)]
    whole = _whole_jacobian(nonlinear, job.problem.bcs, args.repeats, comm)
    rows = comm.gather(rows, root=0)
    if comm.rank == 0:
        _report(rows, whole, comm.size)
        print(f"form compilation (or the cache) on rank 0: {compiling.wall:.1f} s wall, "
              f"{compiling.cpu:.1f} s CPU (the compiler's own CPU is a child's: wall), "
              f"{compiling.calls} forms; C flags {JIT_OPTIONS_3D['cffi_extra_compile_args']}")


def _jit_options(cflags: str | None, cache_dir: str | None) -> None:
    """Replace the 3D forms' compiler flags and cache folder (problem.JIT_OPTIONS_3D)."""
    if cflags is not None:
        JIT_OPTIONS_3D["cffi_extra_compile_args"] = cflags.split()
    if cache_dir is not None:
        JIT_OPTIONS_3D["cache_dir"] = cache_dir


def _forms(nonlinear):
    """(label, form) of each Jacobian block and residual that is not None."""
    for i, row in enumerate(nonlinear.J):
        for j, form in enumerate(row):
            if form is not None:
                yield f"J[{i}][{j}]", form
    for i, form in enumerate(nonlinear.F):
        yield f"F[{i}]", form


def _integrals(form, names: dict, repeats: int) -> list[tuple]:
    """(integral type, region, entities, CPU µs per entity, C lines) of each kernel."""
    from dolfinx.cpp.fem import pack_coefficients, pack_constants
    from dolfinx.fem import IntegralType

    cpp, ufcx, ffi = form._cpp_object, form.ufcx_form, form.module.ffi
    coefficients = pack_coefficients(cpp)  # by (integral type, position in the form)
    constants = np.ascontiguousarray(pack_constants(cpp), dtype=np.float64)
    lines = _kernel_lines(_source(form))
    x = cpp.mesh.geometry.x
    dofmap = cpp.mesh.geometry.dofmaps[0]
    out = []
    types = {IntegralType.cell: 0, IntegralType.exterior_facet: 1}
    for itype, position in types.items():
        first = ufcx.form_integral_offsets[position]
        for k in range(ufcx.form_integral_offsets[position + 1] - first):
            sid = ufcx.form_integral_ids[first + k]
            integral = ufcx.form_integrals[first + k]
            entities = np.asarray(cpp.domains(itype, k)).reshape(-1, 1 if position == 0 else 2)
            w = np.ascontiguousarray(coefficients[(itype, k)], dtype=np.float64)
            cost = _kernel_time(ffi, integral, entities, w, constants, x, dofmap,
                                cpp.function_spaces, repeats)
            name = names.get(sid, str(sid)) if position == 0 else f"facets {sid}"
            out.append(("cell" if position == 0 else "facet", name, len(entities), cost,
                        lines.get(first + k)))
    return out


def _kernel_time(ffi, integral, entities, w, constants, x, dofmap, spaces, repeats):
    """Least CPU µs per entity over `repeats` passes over `entities`."""
    size = 1
    for V in spaces:
        size *= V.dofmap.cell_dofs(0).size * V.dofmap.bs
    A = np.zeros(size)
    pA = ffi.cast("double *", A.ctypes.data)
    pc = ffi.cast("double *", constants.ctypes.data) if constants.size else ffi.NULL
    coords = [np.ascontiguousarray(x[dofmap[e[0]]]) for e in entities]
    local = [np.array([e[1] if len(e) > 1 else 0], dtype=np.int32) for e in entities]
    perm = np.zeros(2, dtype=np.uint8)
    pperm = ffi.cast("uint8_t *", perm.ctypes.data)
    kernel = integral.tabulate_tensor_float64
    args = [(ffi.cast("double *", w[i].ctypes.data) if w.size else ffi.NULL,
             ffi.cast("double *", coords[i].ctypes.data),
             ffi.cast("int *", local[i].ctypes.data)) for i in range(len(entities))]
    best = np.inf
    for _ in range(repeats):
        cpu = time.process_time()
        for pw, px, pl in args:
            kernel(pA, pw, pc, px, pl, pperm, ffi.NULL)
        best = min(best, time.process_time() - cpu)
    return 1e6 * best / max(len(entities), 1)


def _source(form) -> str:
    """The generated C of a form: FFCx's cache keeps it beside the compiled module."""
    if isinstance(form.code, str):
        return form.code
    path = form.module.__file__
    with open(path[:path.index(".cpython")] + ".c") as f:
        return f.read()


def _kernel_lines(code: str) -> dict[int, int]:
    """Lines of C of each integral, by its position in the form's list of integrals."""
    starts = {m.group(1): m.start() for m in re.finditer(r"// Code for integral (\w+)\n", code)}
    ends = {m.group(1): m.start() for m in re.finditer(r"// End of code for integral (\w+)\n",
                                                        code)}
    listing = re.search(r"form_integrals_form_\w+\[\d+\] = \{([^}]*)\}", code)
    order = [s.strip().lstrip("&") for s in listing.group(1).split(",")] if listing else []
    return {k: code.count("\n", starts[n], ends[n]) for k, n in enumerate(order) if n in starts}


def _whole_jacobian(nonlinear, bcs, repeats: int, comm) -> tuple[float, float]:
    """Least (wall s on rank 0, CPU s on this rank) of the Jacobian's assembly into the
    solver's matrix (kernels, insertion, boundary rows)."""
    from dolfinx.fem.petsc import assemble_matrix

    A = nonlinear.A
    walls, cpus = [], []
    for _ in range(repeats):
        comm.barrier()
        wall, cpu = time.perf_counter(), time.process_time()
        A.zeroEntries()
        assemble_matrix(A, nonlinear.J, bcs=bcs)
        A.assemble()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), comm.gather(min(cpus), root=0)


def _report(rows: list[list[tuple]], whole, size: int) -> None:
    print(f"{size} rank(s), load average {os.getloadavg()[0]:.2f}")
    print("form | integral | region | entities per rank | CPU µs per entity per rank | "
          "CPU s per rank | lines of C")
    for parts in zip(*rows):
        label, kind, name = parts[0][:3]
        n = [p[3] for p in parts]
        us = [p[4] for p in parts]
        print(f"{label} | {kind} | {name} | {', '.join(map(str, n))} | "
              f"{', '.join(f'{u:.1f}' for u in us)} | "
              f"{', '.join(f'{a * u * 1e-6:.3f}' for a, u in zip(n, us))} | {parts[0][5]}")
    wall, cpu = whole
    print(f"whole Jacobian assembly: wall {wall:.3f} s (rank 0), CPU "
          f"{', '.join(f'{c:.3f}' for c in cpu)} s per rank")


if __name__ == "__main__":
    main()
