"""The `fingertip` command: one subcommand per job (`fingertip mesh`, later `run`, `sweep`, ...).

To add a subcommand, write `_add_<name>(subparsers)` that builds its parser and sets
`handler=<function(args) -> exit code>`, and list it in `COMMANDS`. Handlers import the heavy
modules (DOLFINx) themselves, so that `fingertip --help` stays instant. A `FingertipError`
raised anywhere becomes a one-line message and exit status 2 (1 for a failed computation).
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import dataclasses
import json
import signal
import sys
import threading
from pathlib import Path

from .datafiles import builtin_names
from .errors import FingertipError, InputError, RunInterrupted
from .routes import AUTO_FIDELITY_TOL, FIDELITY_COARSE

#: The built-in scenes, as the help lists them (the package's data/scenes/).
SCENES = ", ".join(builtin_names("scenes"))


def _folder(text: str) -> Path:
    """--out: an empty one (an unset shell variable, `--out "$OUT"`) would be the working
    folder, where a fresh run removes an earlier run's files by their names."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty (an unset shell variable?): give the folder "
                                         "the results go to, e.g. --out results/1pt")
    return Path(text)


def _add_mesh(subparsers) -> None:
    p = subparsers.add_parser(
        "mesh",
        help="build the tagged fingertip mesh; write XDMF, a PNG picture and a JSON report",
        description="Mesh a fingertip section and write DIR/mesh.xdmf (+ .h5, with cell and "
        "facet tags), DIR/mesh.png (regions and boundary tags) and DIR/mesh_report.json "
        "(element count, quality, region areas against their exact values).",
    )
    p.add_argument(
        "--section", default="male-index", metavar="NAME_OR_TOML",
        help="built-in section name (in the package's data/sections/) or a TOML file "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--min-size", type=float, metavar="H",
        help="element size (mm) in the refinement zone under the pulp (default: the file's [mesh])",
    )
    p.add_argument(
        "--max-size", type=float, metavar="H",
        help="element size (mm) elsewhere in the soft tissue and nail (default: the file's [mesh])",
    )
    p.add_argument(
        "--quad", action="store_true",
        help="recombine into quadrilaterals (for Q2/Q1) instead of triangles",
    )
    p.add_argument("--out", required=True, type=_folder, metavar="DIR", help="output directory")
    p.set_defaults(handler=_run_mesh)


def _add_scene_options(p, check: bool = False) -> None:
    p.add_argument("--config", type=Path, metavar="FILE",
                   help="TOML file of overrides, with the tables of a scene file, merged over it "
                   "(a list, as [[indenters]], replaces the scene's; relative paths in it are "
                   "read from its folder)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override one scene key, e.g. --set model.subcutaneous=drained "
                   "--set section.mesh.min_size=0.05 (repeatable; values read as TOML; "
                   "relative paths from the working directory)")
    p.add_argument("--out", required=not check, type=_folder, metavar="DIR",
                   help="output directory" + (" (with --check: checked if given)" if check
                                              else ""))
    p.add_argument("--quiet", action="store_true", help="no progress display")
    if check:
        p.add_argument("--check", action="store_true",
                       help="check the input without running: every table, the files it "
                       "names, --out writable, a 2D mesh built and the indenters' reach, in "
                       "seconds; exit 0 if fine, 2 with the message if not")


def _add_run(subparsers) -> None:
    p = subparsers.add_parser(
        "run",
        help="run a scene (built in, or a scene TOML file) and write its results",
        description="Run one experiment and write DIR/summary.json, history.csv, "
        "surface_profile.csv, depth_profiles.csv, fields for ParaView (*.bp) and PNG figures. "
        "Results are written step by step; --resume continues an interrupted run. "
        f"Built-in scenes: {SCENES}.",
    )
    p.add_argument("scene", metavar="SCENE",
                   help=f"built-in scene ({SCENES}) or a scene TOML file")
    p.add_argument("--spacing", type=float, metavar="D",
                   help="centre spacing (mm) of the two bars of a 2pt scene")
    p.add_argument("--resume", action="store_true",
                   help="continue the run in DIR from its last saved step")
    p.add_argument("--fidelity", choices=("scene", "auto"), default="scene",
                   help="scene: the scene's own model (default); auto: the cheapest model of "
                   "the fidelity ladder whose key outputs stay within --tol of the full model")
    p.add_argument("--tol", type=float, default=None,
                   help="relative error every key output must reach, in space and time: the "
                   "mesh is refined where they need it (DIR/level-<k>/, the finest copied to "
                   "DIR, DIR/adapt.json) and the steps are checked against tighter ones until "
                   "each estimated error is below it (docs/guide/tolerance.md); with --fidelity "
                   "auto it is the model's tolerance instead (default there: "
                   f"{AUTO_FIDELITY_TOL}) and the mesh follows the scene's [accuracy] tol")
    p.add_argument("--max-levels", type=int, default=None, metavar="N",
                   help="with --tol: at most N runs (default: the scene's [accuracy] "
                   "max_levels, 4)")
    p.add_argument("--fidelity-table", type=Path, metavar="CSV",
                   help="a fidelity.csv from `fingertip study fidelity` for this scene; without "
                   "it, --fidelity auto first runs the ladder on a coarse mesh in DIR/fidelity/")
    p.add_argument("--frequencies", metavar="SPEC", default=None,
                   help="the frequency route: the small-signal response about the pressed "
                   "state at these frequencies (Hz): START:STOP:COUNT (log-spaced) or a comma "
                   "list; writes frequency_response.csv, receptor_transfer.csv, summary.json "
                   "and figures (also run when the scene has a [harmonic] table)")
    p.add_argument("--state", choices=("held", "relaxed"), default=None,
                   help="with the frequency route: the pressed state, held at the end of the "
                   "pre-indentation (default) or relaxed to the long-term equilibrium")
    _add_scene_options(p, check=True)
    p.set_defaults(handler=_run_or_check)


def _add_sweep(subparsers) -> None:
    p = subparsers.add_parser(
        "sweep",
        help="run a scene over values of one input (--param), or a 2pt scene over bar "
        "spacings (--spacings)",
        description="--param KEY --values V1 V2 ... (or --factors F1 F2 ...: multiples of the "
        "scene's own value, a number or a list): the scene once per value into DIR/<label>/, "
        "then DIR/sweep.csv (key outputs per value), DIR/summary.json and DIR/sweep.png. "
        "--spacings D1 D2 ... (two-point scenes): DIR/d<spacing>/ per spacing, then "
        "DIR/normalized_variation.csv, DIR/summary.json (with threshold_mm and its criterion) "
        "and DIR/normalized_variation.png. Under mpiexec the runs go side by side, one group "
        "of ranks each.",
    )
    p.add_argument("scene", metavar="SCENE",
                   help=f"a built-in scene ({SCENES}) or a scene TOML file")
    p.add_argument("--spacings", type=float, nargs="+", metavar="D",
                   help="centre spacings in mm of a 2pt scene, e.g. 1.5 2 3 4")
    p.add_argument("--spots", action="store_true",
                   help="with --spacings: mesh a fine disc (section.mesh.spot_size, spot_zone) "
                   "at each point the variations are read, under both bars and midway at the "
                   "output depth (2pt with --set section.mesh.min_size=0.14: every key output "
                   "within 1 %% at 1.5-4 mm for 0.4 of the 0.1 mm mesh's CPU time, which is "
                   "not within 1 %% everywhere)")
    p.add_argument("--param", metavar="KEY",
                   help="the scene key to vary, e.g. materials.subcutaneous.permeability.k0 "
                   "or materials.skin.mu")
    p.add_argument("--values", nargs="+", metavar="V",
                   help="values of --param (read as TOML: 1e-2, [0.1, 0.2])")
    p.add_argument("--factors", type=float, nargs="+", metavar="F",
                   help="multiply the scene's value of --param by each factor")
    p.add_argument("--resume", action="store_true",
                   help="continue a sweep stopped part-way: each run with a checkpoint in "
                   "DIR continues from it (a finished one is kept), the others start")
    _add_scene_options(p, check=True)
    p.set_defaults(handler=_sweep_or_check)


def _add_study(subparsers) -> None:
    p = subparsers.add_parser(
        "study",
        help="studies: accuracy (error against cost), fidelity (which physics a scene needs), "
        "stability (where methods fail), acuity (gratings and gaps: SA1 thresholds)",
        description="accuracy: the scene over mesh sizes, element families and time steps, "
        "errors against a Richardson estimate, the Pareto front of error against wall time "
        "(DIR/accuracy.csv, .md, .png). "
        "fidelity: the scene with a ladder of models from a linear-elastic "
        "continuum to the full biphasic model, each scored against the full one "
        "(DIR/fidelity.csv, .md, .png). stability: known numerical failure modes measured "
        "beside the methods that work (DIR/stability.csv, .md, figures). acuity: gratings "
        "and gaps pressed into the section, the SA1 population's spike counts and the widths "
        "an ideal observer tells apart (d' = 1), next to the measured thresholds "
        "(DIR/acuity.md, acuity.csv, counts.csv, acuity.png; coarse mesh unless --full); "
        "finished runs in DIR that sampled the same sites are reused and counted again with "
        "the receptor set's current calibration.",
    )
    p.add_argument("kind", choices=("accuracy", "fidelity", "stability", "acuity"))
    p.add_argument("--scene", default=None,
                   help="scene of the accuracy and fidelity studies (default: 1pt for accuracy, "
                   "line-load for fidelity)")
    p.add_argument("--full", action="store_true",
                   help="full resolution (default: the coarse settings CI runs)")
    p.add_argument("--adapt-tol", type=float, default=None, metavar="TOL",
                   help="accuracy: also run the adaptive mesh loop with this tolerance from "
                   "the study's coarsest mesh and check its estimated errors against the "
                   "study's reference (DIR/adaptive/)")
    p.add_argument("--widths", type=float, nargs="+", metavar="W", default=None,
                   help="acuity: ridge (= groove) widths of the gratings in mm (default "
                   "0.5 0.75 1 1.5 2)")
    p.add_argument("--gaps", type=float, nargs="*", metavar="G", default=None,
                   help="acuity: gaps in the 4 mm bar in mm (default 0.5 1 1.5 2; --3d: 1; "
                   "--3d --gaps with no value: the orientation task only)")
    p.add_argument("--3d", dest="three_d", action="store_true",
                   help="acuity: on the 3D fingertip (scene grating-3d): the grating along "
                   "vs across the finger and the gap, one run at a time per rank group "
                   "(default width 1, gap 1)")
    _add_scene_options(p)
    p.set_defaults(handler=_run_study)


COMMANDS = [_add_mesh, _add_run, _add_sweep, _add_study]


def _run_study(args) -> int:
    if args.kind == "acuity":
        return _run_acuity(args)
    if args.kind == "stability":
        from .studies.stability import run_stability_study

        run_stability_study(args.out, coarse=not args.full)
        _rank0_print(f"stability study written to {args.out}/stability.md")
        return 0
    if args.kind == "accuracy":
        from .studies.accuracy import run_accuracy_study

        if args.adapt_tol is not None and not 0 < args.adapt_tol < 1:
            raise InputError(f"--adapt-tol {args.adapt_tol}", "must be a relative error in "
                             "(0, 1).", "give e.g. --adapt-tol 0.05.")
        result = run_accuracy_study(args.scene or "1pt", args.out, coarse=not args.full,
                                    overrides=_scene_overrides(args), progress=not args.quiet,
                                    adapt_tol=args.adapt_tol)
        _rank0_print(result["sentence"])
        if result["adaptive"]:
            _rank0_print(result["adaptive"]["sentence"])
        _rank0_print(f"accuracy table written to {args.out}/accuracy.md")
        return 0
    from .studies.fidelity import run_fidelity_study

    coarse = [] if args.full else list(FIDELITY_COARSE)
    rows = run_fidelity_study(args.scene or "line-load", args.out,
                              coarse + _scene_overrides(args),
                              progress=not args.quiet)
    for r in rows:
        # A rung that failed has no error (its max_error is inf): say so, as fidelity.md does.
        verdict = ("failed (the reason: fidelity.md)" if r.get("failure") else
                   f"largest error {100 * r['max_error']:6.2f} %")
        _rank0_print(f"{r['model']:>18}: {r['wall_time_s']:6.1f} s, {verdict}")
    _rank0_print(f"fidelity table written to {args.out}/fidelity.md")
    return 0


def _run_acuity(args) -> int:
    """`fingertip study acuity`: the table printed, the files in --out."""
    from .studies import acuity

    if args.three_d:
        gaps = acuity.GAPS_3D if args.gaps is None else args.gaps
        result = acuity.run_acuity_3d(args.out, args.widths or acuity.WIDTHS_3D,
                                      gaps, _scene_overrides(args),
                                      progress=not args.quiet)
        _rank0_print(f"Criterion: {result['criterion']}.\n")
        _rank0_print(acuity.acuity_table_3d(result))
        _rank0_print(f"acuity table written to {args.out}/acuity.md")
        return 0
    coarse = [] if args.full else list(acuity.COARSE)
    result = acuity.run_acuity(args.out, args.widths or acuity.WIDTHS, args.gaps or acuity.GAPS,
                               coarse + _scene_overrides(args), progress=not args.quiet)
    _rank0_print(f"Criterion: {result['criterion']}.\n")
    _rank0_print(acuity.acuity_table(result))
    _rank0_print(f"acuity table written to {args.out}/acuity.md")
    return 0


def _scene_overrides(args) -> list[str]:
    """--config FILE's keys as KEY=VALUE overrides (its relative paths read from its folder),
    followed by the --set ones; each names its source (`--config FILE`, `--set KEY=VALUE`) in
    an error message."""
    from .datafiles import read_toml
    from .scene import Override, anchor_paths, overrides_as_text

    overrides = []
    if args.config is not None:
        where = f"--config {args.config}"
        if not args.config.is_file():
            raise InputError(where, "no such file.",
                             "give a TOML file with the tables of a scene file.")
        try:
            data = read_toml(args.config)
        except InputError as error:
            raise InputError(where, error.problem, error.fix) from None
        overrides += overrides_as_text(anchor_paths(data, args.config.parent), source=where)
    return overrides + [Override(text, f"--set {text}") for text in args.overrides]


def _run_or_check(args) -> int:
    """`fingertip run`, or with --check the scene checked without running (checks.py)."""
    if args.check:
        if args.tol is not None and not 0 < args.tol < 1:
            raise InputError(f"--tol {args.tol}", "must be a relative error in (0, 1).",
                             "give e.g. --tol 0.01 for 1 %.")
        if args.frequencies is not None:
            from .harmonic_options import parse_frequencies

            parse_frequencies(args.frequencies, f"--frequencies {args.frequencies}")
        overrides = _scene_overrides(args)
        _check_run_keys(args, overrides)
        return _print_check(args, overrides, args.spacing)
    _need_out(args)
    return _run_scene(args)


def _check_run_keys(args, overrides) -> None:
    """--check of a run: what the run itself refuses before its first step (`check_route`:
    options off its route, key outputs its comparisons cannot read) is refused here too."""
    from .routes import check_route
    from .scene import load_scene

    check_route(load_scene(args.scene, overrides, spacing=args.spacing), tol=args.tol,
                max_levels=args.max_levels, frequencies=args.frequencies, state=args.state,
                fidelity=args.fidelity, fidelity_table=args.fidelity_table,
                resume=args.resume)


def _need_out(args) -> None:
    """--out is optional for --check only."""
    if args.out is None:
        raise InputError("--out", "is required: the folder the results go to.",
                         "give --out DIR (or --check to check the input only).")


def _sweep_or_check(args) -> int:
    """`fingertip sweep`, or with --check each of its scenes loaded and the first checked."""
    from .scene import Override, load_scene

    if not args.check:
        _need_out(args)
        return _run_sweep(args)
    overrides, spacings = _scene_overrides(args), args.spacings or [None]
    if args.param:  # the sweep's table is the key outputs: refused before the first run
        from .keys import check_scene

        check_scene(load_scene(args.scene, overrides), f"sweep {args.scene} --param {args.param}")
    if args.param and args.values:
        for text in args.values:
            load_scene(args.scene, [*overrides, Override(f"{args.param}={text}",
                                                         f"--param {args.param} --values {text}")])
    elif args.param and args.factors:
        from .scene import scene_record, toml_value
        from .studies.parameters import scaled_value, value_at

        base = value_at(scene_record(load_scene(args.scene, overrides)), args.param)
        for factor in args.factors:
            value = toml_value(scaled_value(base, factor, args.param))
            load_scene(args.scene, [*overrides, Override(f"{args.param}={value}",
                                                         f"--param {args.param} --factors "
                                                         f"{factor:g}")])
    for spacing in spacings[1:]:
        load_scene(args.scene, overrides, spacing=spacing)
    return _print_check(args, overrides, spacings[0])


def _print_check(args, overrides: list[str], spacing: float | None) -> int:
    """Check args.scene with `overrides` (checks.py) and print the report."""
    from .checks import check

    for line in check(args.scene, args.out, overrides, spacing=spacing):
        _rank0_print(line)
    return 0


def _run_scene(args) -> int:
    """`fingertip run`: the scene by its route (routes.py, as `ft.run`), then one line."""
    from mpi4py import MPI

    from .routes import run

    try:
        result = run(args.scene, args.out, overrides=_scene_overrides(args), spacing=args.spacing,
                     tol=args.tol, max_levels=args.max_levels, fidelity=args.fidelity,
                     fidelity_table=args.fidelity_table, frequencies=args.frequencies,
                     state=args.state, resume=args.resume, progress=not args.quiet,
                     say=_rank0_print)
    except RunInterrupted as stop:
        if getattr(stop, "route", None) != "time":
            raise
        if stop.time > 0:
            _rank0_print(f"interrupted at t = {stop.time:.6g} s; continue with: "
                         f"{_resume_command(args.argv, MPI.COMM_WORLD.size)}")
        else:  # within the first step's solve: no checkpoint yet, --resume would be refused
            _rank0_print("interrupted at t = 0 s, before the first step was done: there is "
                         "nothing to resume; start again with: "
                         f"{_resume_command(args.argv, MPI.COMM_WORLD.size, resume=False)}")
        return 130
    {"time": _print_run, "adaptive": _print_adaptive,
     "frequency": _print_frequency}[result.route](result)
    return 0


def _print_run(result) -> None:
    summary = result.summary
    peak = (f"{summary['peak_force_N']:.4g} N" + (" (half model: x2 for the whole finger)"
                                                   if summary["mirror_factor"] == 2 else "")
            if "peak_force_N" in summary else f"{summary['peak_force_N_per_mm']:.4g} N/mm")
    _rank0_print(
        f"{summary['scene']}: {summary['time_steps']} steps, "
        f"{summary['newton_iterations']} Newton iterations, {summary['wall_time_s']:.1f} s; "
        f"peak force {peak}, max penetration {1e3 * summary['max_penetration_mm']:.3g} µm; "
        f"results in {result.out}"
    )


def _resume_command(argv: list[str], ranks: int, resume: bool = True) -> str:
    """The command line that continues this run: the same one, with --resume (without it,
    `resume=False`: the run starts again)."""
    import shlex

    launch = f"mpiexec -n {ranks} " if ranks > 1 else ""
    argv = [a for a in argv if a != "--resume"]
    return f"{launch}fingertip {shlex.join([*argv, *(['--resume'] if resume else [])])}"


def _print_frequency(result) -> None:
    summary = result.summary
    # only the peaks the grid resolves are named; the others as bands to refine
    peaks = ", ".join(f"{f:.3g}" for f in summary["resonances_Hz"]["probe_held"]) or "none"
    warning = summary["resonance_warning"]
    _rank0_print(
        f"{summary['scene']['name']}: {summary['dofs']} dofs, "
        f"{len(summary['harmonic']['frequencies_Hz'])} frequencies in "
        f"{summary['wall_time_s']:.1f} s (pressed state "
        f"{summary['pressed_state']['wall_time_s']:.1f} s); resonances resolved (|K| maxima, "
        f"probe held): {peaks}{' Hz' if peaks != 'none' else ''}"
        f"{'; ' + warning if warning else ''}; results in {result.out}")


def _print_adaptive(result) -> None:
    from .studies.adaptivity import read_adapt

    cost = read_adapt(result.out)["cost"]
    _rank0_print(f"{cost['levels']} levels, {cost['wall_time_s']:.1f} s of time stepping "
                 f"({cost['elapsed_s']:.1f} s in all); the finest level's results in "
                 f"{result.out}, the loop in {result.out}/adapt.json")


def _run_sweep(args) -> int:
    if args.spacings and args.param:
        raise InputError("sweep", "--spacings and --param both given.", "give one of them.")
    if args.spots and not args.spacings:
        raise InputError("sweep --spots", "places the discs at the bars of a spacing sweep.",
                         "give --spacings too.")
    if args.param:
        return _run_parameter_sweep(args)
    if not args.spacings:
        raise InputError("sweep", "nothing to sweep over.", "give --param KEY or --spacings.")
    from .studies.sweep import run_sweep

    result = run_sweep(args.scene, args.spacings, args.out, _scene_overrides(args),
                       progress=not args.quiet, spots=args.spots, resume=args.resume)
    threshold = result["threshold_mm"]
    _rank0_print(
        f"2pt sweep over {len(args.spacings)} spacings: threshold "
        f"{'not bracketed' if threshold is None else f'{threshold:.2f} mm'} "
        f"({result['threshold_criterion']}); results in {args.out}"
    )
    if "population" in result:
        pop = result["population"]
        def fmt(x):
            return "not bracketed" if x is None else f"{x:.2f} mm"
        _rank0_print(f"SA1 population: threshold {fmt(pop['threshold_mm'])}, smallest resolved "
                     f"spacing {fmt(pop['smallest_resolved_mm'])} ({pop['criterion']})")
    return 0


def _run_parameter_sweep(args) -> int:
    from .keys import KEY_OUTPUTS
    from .scene import parse_override
    from .studies.parameters import parameter_sweep

    if (args.values is None) == (args.factors is None):
        raise InputError(f"--param {args.param}", "needs either --values or --factors.",
                         "give one of them.")
    values = None
    if args.values is not None:
        values = [parse_override(f"v={text}")[1] for text in args.values]
    result = parameter_sweep(args.scene, args.param, args.out, values=values,
                             factors=args.factors, overrides=_scene_overrides(args),
                             progress=not args.quiet, resume=args.resume)
    for row in result["rows"]:
        _rank0_print(f"{row['label']:>24}: " + ", ".join(
            f"{key.short} {row[key.column]:.5g}" for key in KEY_OUTPUTS))
    _rank0_print("columns: " + ", ".join(f"{k.short} = {k.column}" for k in KEY_OUTPUTS))
    _rank0_print(f"sweep over {args.param} written to {args.out}/sweep.csv")
    return 0


def _run_mesh(args) -> int:
    """`fingertip mesh`: the 2D section's triangles (or quadrilaterals) and its report."""
    from .geometry.fingertip3d import section_dimension
    from .geometry.mesh import build_mesh, report_dict
    from .geometry.section import load_section
    from .plotting.figures import plot_tagged_mesh

    if section_dimension(args.section) == 3:
        return _run_mesh3d(args)
    section = _with_mesh_options(
        load_section(args.section),
        {"min_size": args.min_size, "max_size": args.max_size, "quadrilateral": args.quad or None},
    )
    console, fm, report = _mesh_and_write(
        lambda comm, progress: build_mesh(section, comm, progress=progress), args.out,
        lambda fm, path: plot_tagged_mesh(fm, path, title=f"section '{section.name}'"),
        lambda fm: report_dict(fm, section))
    _print_mesh_report(console, fm.report, section.name, report["areas_mm2"], "area (mm²)",
                       6, f"{fm.report.cell_type}s", args.out)
    return 0


def _run_mesh3d(args) -> int:
    """`fingertip mesh` of a 3D fingertip file (`dimension = 3`): tetrahedra, the same outputs."""
    from .geometry.fingertip3d import load_fingertip3d
    from .geometry.mesh3d import build_mesh3d, report_dict3d
    from .plotting.fieldplots import plot_tagged_mesh3d

    if args.quad:
        raise InputError("--quad", "3D meshes are tetrahedral only.", "leave out --quad.")
    tip = load_fingertip3d(args.section)
    tip = dataclasses.replace(tip, section=_with_mesh_options(
        tip.section, {"min_size": args.min_size, "max_size": args.max_size}))
    title = f"'{tip.name}'" + (" (half: x >= 0)" if tip.half else "")
    console, fm, report = _mesh_and_write(
        lambda comm, progress: build_mesh3d(tip, comm, progress=progress), args.out,
        lambda fm, path: plot_tagged_mesh3d(fm, path, title=title),
        lambda fm: report_dict3d(fm, tip))
    _print_mesh_report(console, fm.report, tip.name, report["volumes_mm3"], "volume (mm³)",
                       4, "tetrahedra", args.out)
    return 0


def _mesh_and_write(build, out, plot, report_of):
    """Mesh with a progress line, then write mesh.xdmf, mesh.png and mesh_report.json into
    `out`: (console, mesh, report)."""
    from mpi4py import MPI
    from rich.console import Console

    from .geometry.mesh import write_xdmf

    comm = MPI.COMM_WORLD
    console = Console(stderr=True, quiet=comm.rank != 0)
    with console.status("meshing") as status:
        fm = build(comm, lambda message: status.update(message))
        status.update("writing the mesh, picture and report")
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        write_xdmf(fm, out / "mesh.xdmf")
        plot(fm, out / "mesh.png")
        report = report_of(fm)
    if comm.rank == 0:
        (out / "mesh_report.json").write_text(json.dumps(report, indent=2) + "\n")
    return console, fm, report


def _print_mesh_report(console, r, name: str, measures: dict, measure: str, digits: int,
                       cells: str, out) -> None:
    """The region sizes against their closed forms, and the mesh's counts and quality."""
    from rich.table import Table

    table = Table(title=f"mesh of '{name}' ({r.seconds:.2f} s on rank 0)")
    for column in ("region", measure, f"exact ({measure.split('(')[1]}", "relative error"):
        table.add_column(column, justify="right")
    for region, m in measures.items():
        table.add_row(region, f"{m['mesh']:.{digits}f}", f"{m['exact']:.{digits}f}",
                      f"{m['relative_error']:+.2e}")
    console.print(table)
    console.print(
        f"{r.num_cells} {cells}, {r.num_vertices} vertices; quality (minSICN) "
        f"min {r.min_quality:.3f}, mean {r.mean_quality:.3f}; edges {r.min_edge:.4f}–"
        f"{r.max_edge:.4f} mm\nwrote {out}/mesh.xdmf (+ .h5), mesh.png, mesh_report.json"
    )


def _with_mesh_options(section, given: dict):
    """`section` with the mesh options given on the command line (None: keep the file's)."""
    given = {key: value for key, value in given.items() if value is not None}
    try:
        return dataclasses.replace(section, mesh=dataclasses.replace(section.mesh, **given))
    except InputError as e:
        options = " ".join(f"--{k.replace('_', '-')} {v}" for k, v in given.items())
        raise InputError(f"{options} ({e.where})", e.problem, e.fix) from None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fingertip",
        description="Finite-strain fingertip biomechanics (skin, subcutaneous tissue, bone, "
        "nail) under rigid indenters, in FEniCSx. Units: mm, N, s, MPa.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    return parser


#: glibc's mallopt parameters (malloc.h).
M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4


def keep_freed_memory() -> bool:
    """Make glibc's malloc keep the memory this process frees, for its next allocations.

    By default glibc maps each block above its mmap threshold (at most 32 MiB) afresh and
    unmaps it when freed, and returns the heap's free top to the system: the next allocation
    of the same size touches new pages, each a page fault the kernel zeroes. MUMPS allocates
    and frees its work arrays (hundreds of MB in 3D) at every factorisation, so a 3D run spent
    a sixth of its CPU in the kernel. Without mmap and trimming, freed blocks are reused.
    Measured on one step of `line-load-3d` (9 LU factorisations, 2 ranks): minor page faults
    2.6 M -> 0.54 M, system CPU 15.7 -> 5.0 s, peak memory unchanged
    (docs/benchmarks/solvers-3d.md, "Page faults"). Set by the command, for its process; the
    library's API leaves a Python session's allocator alone (a notebook would keep what it
    frees). Returns whether the allocator took the settings (False off glibc)."""
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    mallopt = getattr(libc, "mallopt", None)
    if mallopt is None:
        return False
    return bool(mallopt(M_MMAP_MAX, 0)) and bool(mallopt(M_TRIM_THRESHOLD, 2**31 - 1))


def main(argv: list[str] | None = None) -> int:
    """Run the command line `argv` (default: sys.argv[1:]); return the exit status."""
    keep_freed_memory()
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help (0) or a malformed command line (2, message printed)
        return int(e.code or 0)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # for the line that resumes
    restore = _term_interrupts()
    try:
        return args.handler(args)
    except FingertipError as e:
        _rank0_print(f"fingertip {args.command}: error: {e}")
        return 2 if isinstance(e, InputError) else 1
    except RunInterrupted as e:  # a run inside a sweep or study: stopped at a step boundary
        from mpi4py import MPI

        again = (f"; continue with: {_resume_command(args.argv, MPI.COMM_WORLD.size)}"
                 if args.command == "sweep" else "")
        _rank0_print(f"fingertip {args.command}: {e}; its files are written{again}")
        return 130
    except KeyboardInterrupt as e:  # outside a run's steps: loading, meshing, between runs
        return _interrupted_outside_a_step(args.command, e.args[0] if e.args else "SIGINT")
    finally:
        restore()


def _interrupted_outside_a_step(command: str, signal_name: str) -> int:
    """One line and exit 130. Under mpiexec the ranks meet the signal at different places:
    one may wait in a collective for a rank that has stopped (measured: a hang, or a rank's
    SEGV as the others finalised), so the rank that stops ends them all (MPI_Abort)."""
    message = (f"fingertip {command}: interrupted by {signal_name} outside a time step (while "
               "starting, or between runs): no step was cut short, the files written are "
               "whole. Fix: give the command again (with --resume for a run that has a "
               "checkpoint).")
    world = _world()
    if world.size == 1:
        _rank0_print(message)
        return 130
    print(message, file=sys.stderr, flush=True)  # this rank's: the others may never print
    world.Abort(130)
    return 130  # (not reached)


def _world():
    from mpi4py import MPI

    return MPI.COMM_WORLD


def _raise_interrupt(number, frame) -> None:
    raise KeyboardInterrupt(signal.Signals(number).name)


def _term_interrupts():
    """Until a run installs its own handlers (`runner.Interrupts`: while the libraries load,
    the scene is read, a sweep is between two runs), SIGTERM stops the command as Ctrl-C does,
    with one line and exit 130. Without this, PETSc's handler, installed when petsc4py starts
    PETSc (so PETSc is started first here), takes SIGTERM: `PETSC ERROR: Caught signal number
    15 Terminate` and an MPI_Abort. A SIGTERM ignored by the caller stays ignored. Returns the
    function that puts the previous handler back (called when the command returns)."""
    from petsc4py import PETSc  # noqa: F401  (PetscInitialize installs PETSc's signal handlers)

    previous = signal.getsignal(signal.SIGTERM)
    if previous is signal.SIG_IGN or threading.current_thread() is not threading.main_thread():
        return lambda: None
    signal.signal(signal.SIGTERM, _raise_interrupt)
    return lambda: signal.signal(signal.SIGTERM, previous if previous is not None
                                 else signal.SIG_DFL)


def _rank0_print(message: str) -> None:
    from mpi4py import MPI

    if MPI.COMM_WORLD.rank == 0:
        print(message, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
