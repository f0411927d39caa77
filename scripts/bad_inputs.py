"""Mistakes a user makes, tried: each must stop with exit 2 (1 for a failed computation) and
one line naming where the bad value came from and the fix.

    python scripts/bad_inputs.py [--write docs/guide/troubleshooting.md]

runs every case of CASES in this process (the command line through `cli.main`, mostly with
`--check`, which stops before any time step; the Python ones through the API), prints the
table (input, exit code, the message's first line) and, with --write, puts it into the page
between the markers `<!-- bad-inputs:start -->` and `<!-- bad-inputs:end -->`. It exits 1 if
a case ends otherwise than its `code` or its message does not name `names`.
tests/test_bad_inputs.py runs the same cases.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import traceback
from dataclasses import dataclass
from pathlib import Path

#: The package's folder, shortened in the table (built-in files are named by their path).
PACKAGE = str(Path(__file__).resolve().parents[1] / "fingertip_dolfinx")
START, END = "<!-- bad-inputs:start -->", "<!-- bad-inputs:end -->"

#: Files the cases name, written into a fresh folder `{d}` (paths relative to it).
FILES = {
    "scene/indenter.toml": 'shape = "cylinder"\nradius = 4.0\n',
    "scene/good.toml": ('name = "mine"\n[[indenters]]\nfile = "indenter.toml"\n'
                        "[protocol]\ndepth = 0.5\nramp_time = 1.0\nend_time = 1.0\n"),
    "scene/prony.toml": ('name = "prony"\n[[indenters]]\nfile = "bar"\n[protocol]\ndepth = 0.5\n'
                         "ramp_time = 1.0\nend_time = 1.0\n[materials.skin.prony]\ng = [0.5]\n"),
    "scene/typo.toml": ('[[indenters]]\nfile = "bar"\n[protocol]\ndepth = 0.5\nramp_time = 1.0\n'
                        "end_time = 1.0\n[output]\ntime = [1.0]\n"),
    "scene/bad-materials.toml": ("[[indenters]]\nfile = \"bar\"\n[protocol]\ndepth = 0.5\n"
                                 "ramp_time = 1.0\nend_time = 1.0\n[materials]\n"
                                 'set = "soft.toml"\n'),
    "scene/soft.toml": None,  # wu2004.toml with a negative bone modulus (written below)
    "scene/bad-indenter.toml": ("[[indenters]]\nfile = \"sharp.toml\"\n[protocol]\ndepth = 0.5\n"
                                "ramp_time = 1.0\nend_time = 1.0\n"),
    "scene/sharp.toml": 'shape = "cylinder"\nradius = -1.0\n',
    "scene/broken.toml": "[protocol\ndepth = 1\n",
    "scene/latin1.toml": 'description = "Haut, Unterhautgewebe, Kn\xf6chel"\n'.encode("latin-1"),
    "config/typo.toml": "[protocol]\ndept = 0.5\n",
    "config/cylinder.toml": '[[indenters]]\nfile = "indenter.toml"\nradius = 5.0\n',
    "config/indenter.toml": 'shape = "cylinder"\nradius = 4.0\n',
    "config/missing.toml": '[[indenters]]\nfile = "nowhere.toml"\n',
    "config/broken.toml": "protocol.depth = = 1\n",
    "empty/.keep": "",
    "a-file": "not a folder\n",
}


@dataclass(frozen=True)
class Case:
    """One mistake: `argv` for `fingertip` (or `python`: code run with `ft` imported, whose
    InputError counts as exit 2), the exit code it must end with and a text its message must
    contain (the source it names); `{d}` is the fixtures' folder."""

    mistake: str
    argv: tuple[str, ...] = ()
    code: int = 2
    names: str = ""
    python: str = ""
    #: Builds a mesh or a problem (a second or more): tests/test_bad_inputs.py runs it as slow.
    slow: bool = False


CASES = [
    Case("misspelled scene name", ("run", "1tp", "--check"), names="1tp: no such scene"),
    Case("misspelled key, --set", ("run", "1pt", "--check", "--set", "protocol.dept=0.5"),
         names="--set protocol.dept=0.5"),
    Case("protocol kind changed alone", ("run", "1pt", "--check", "--set",
                                         "protocol.kind=piecewise-linear"),
         names="--set protocol.kind=piecewise-linear"),
    Case("end before the output times", ("run", "line-load", "--check", "--set",
                                         "protocol.end_time=50"),
         names="--set protocol.end_time=50"),
    Case("finest mesh size above the coarsest", ("run", "1pt", "--check", "--set",
                                                 "section.mesh.min_size=5"),
         names="--set section.mesh.min_size=5"),
    Case("misspelled table, --set", ("run", "1pt", "--check", "--set", "protcol.depth=0.5"),
         names="--set protcol.depth=0.5"),
    Case("text for a number", ("run", "1pt", "--check", "--set", "protocol.depth=deep"),
         names="--set protocol.depth=deep"),
    Case("negative permeability", ("run", "1pt", "--check", "--set",
                                   "materials.subcutaneous.permeability.k0=-1e-3"),
         names="--set materials.subcutaneous.permeability.k0"),
    Case("Poisson's ratio above 0.5", ("run", "1pt", "--check", "--set", "materials.bone.nu=0.6"),
         names="--set materials.bone.nu=0.6"),
    Case("Prony ratios without times", ("run", "1pt", "--check", "--set",
                                        "materials.skin.prony.g=[0.5]"),
         names="--set materials.skin.prony.g"),
    Case("bone wider than the finger", ("run", "1pt", "--check", "--set", "section.bone.width=20"),
         names="--set section.bone.width=20"),
    Case("negative mesh size", ("run", "1pt", "--check", "--set", "section.mesh.min_size=-0.1"),
         names="--set section.mesh.min_size"),
    Case("indenter beside the finger", ("run", "1pt", "--check", "--set",
                                        "indenters.0.centre_x=12"),
         names="--set indenters.0.centre_x=12", slow=True),
    Case("protocol that never presses", ("run", "1pt", "--check", "--set", "protocol.depth=0"),
         names="--set protocol.depth=0"),
    Case("ramp longer than the run", ("run", "1pt", "--check", "--set", "protocol.end_time=0.5"),
         names="--set protocol.end_time=0.5"),
    Case("output time after the end", ("run", "1pt", "--check", "--set", "output.times=[5.0]"),
         names="--set output.times"),
    Case("negative output depth", ("run", "1pt", "--check", "--set", "output.depths=[-1]"),
         names="--set output.depths"),
    Case("infinite depth", ("run", "1pt", "--check", "--set", "protocol.depth=inf"),
         names="--set protocol.depth=inf"),
    Case("NaN end time", ("run", "1pt", "--check", "--set", "protocol.end_time=nan"),
         names="--set protocol.end_time=nan: protocol.end_time: must be finite"),
    Case("a list for a number", ("run", "1pt", "--check", "--set", "protocol.depth=[1, 2]"),
         names="--set protocol.depth=[1, 2]"),
    Case("a number for a table", ("run", "1pt", "--check", "--set", "protocol=5"),
         names="--set protocol=5"),
    Case("depth in µm, read as mm", ("run", "1pt", "--check", "--set", "protocol.depth=1000"),
         names="--set protocol.depth=1000"),
    Case("bone modulus in Pa", ("run", "1pt", "--check", "--set", "materials.bone.E=1.7e10"),
         names="--set materials.bone.E=1.7e10"),
    Case("skin moduli in Pa", ("run", "1pt", "--check", "--set",
                               "materials.skin.mu=[-75940, 11380, 65720]"),
         names="--set materials.skin.mu"),
    Case("NaN output time", ("run", "1pt", "--check", "--set", "output.times=[nan]"),
         names="--set output.times=[nan]"),
    Case("a number for a list", ("run", "1pt", "--check", "--set", "output.times=5"),
         names="--set output.times=5: output.times: must be a list"),
    Case("depth curve outside the finger", ("run", "1pt", "--check", "--set",
                                            "output.depths=[100]"),
         names="--set output.depths=[100]"),
    Case("unclosed list in --set", ("run", "1pt", "--check", "--set", "output.times=[1,"),
         names="--set output.times=[1,: [1, is not a TOML value"),
    Case("unknown model option value", ("run", "1pt", "--check", "--set",
                                        "model.subcutaneous=dry"),
         names="--set model.subcutaneous=dry"),
    Case("unknown linear solver", ("run", "1pt", "--check", "--set", "solver.linear=fast"),
         names="--set solver.linear=fast"),
    Case("negative first time step", ("run", "1pt", "--check", "--set", "steps.dt_initial=-1"),
         names="--set steps.dt_initial=-1"),
    Case("text for a step size", ("run", "1pt", "--check", "--set", "steps.dt_initial=abc"),
         names="--set steps.dt_initial=abc: steps.dt_initial: must be a finite number"),
    Case("a fraction for a count", ("run", "1pt", "--check", "--set", "steps.max_cuts=1.5"),
         names="--set steps.max_cuts=1.5"),
    Case("negative contact stiffness", ("run", "1pt", "--check", "--set",
                                        "model.contact_gamma0=-1"),
         names="--set model.contact_gamma0=-1"),
    Case("text for a switch", ("run", "1pt", "--check", "--set", "output.pictures=yes"),
         names="--set output.pictures=yes"),
    Case("missing indenter file", ("run", "1pt", "--check", "--set", "indenters.0.file=cyl"),
         names="--set indenters.0.file=cyl"),
    Case("missing materials set", ("run", "1pt", "--check", "--set", "materials.set=wu2040"),
         names="--set materials.set=wu2040"),
    Case("missing section file", ("run", "1pt", "--check", "--set", "section.file=male"),
         names="--set section.file=male"),
    Case("missing receptor set", ("run", "1pt", "--check", "--set", "output.receptors=all"),
         names="--set output.receptors=all"),
    Case("list index out of range", ("run", "1pt", "--check", "--set", "indenters.1.radius=2"),
         names="--set indenters.1.radius=2"),
    Case("a name for a list of tables", ("run", "1pt", "--check", "--set", "indenters=cylinder"),
         names="--set indenters=cylinder"),
    Case("--set without =", ("run", "1pt", "--check", "--set", "protocol.depth"),
         names="--set protocol.depth"),
    Case("--out not writable", ("run", "1pt", "--check", "--out", "/proc/fingertip"),
         names="--out /proc/fingertip"),
    Case("--out is a file", ("run", "1pt", "--check", "--out", "{d}/a-file"),
         names="--out {d}/a-file"),
    Case("--tol out of range", ("run", "1pt", "--check", "--tol", "2"), names="--tol 2"),
    Case("NaN bar spacing", ("run", "2pt", "--check", "--spacing", "nan"),
         names="spacing nan: spacing: must be finite"),
    Case("frequency range backwards", ("run", "vibrotactile", "--check", "--frequencies",
                                       "1000:1:40"), names="--frequencies 1000:1:40"),
    Case("--config missing", ("run", "1pt", "--check", "--config", "{d}/config/nope.toml"),
         names="--config {d}/config/nope.toml"),
    Case("--config not TOML", ("run", "1pt", "--check", "--config", "{d}/config/broken.toml"),
         names="--config {d}/config/broken.toml"),
    Case("--config misspelled key", ("run", "1pt", "--check", "--config", "{d}/config/typo.toml"),
         names="--config {d}/config/typo.toml"),
    Case("--config names a missing file", ("run", "1pt", "--check", "--config",
                                           "{d}/config/missing.toml"),
         names="--config {d}/config/missing.toml"),
    Case("scene file misspelled key", ("run", "{d}/scene/typo.toml", "--check"),
         names="{d}/scene/typo.toml"),
    Case("scene file not TOML", ("run", "{d}/scene/broken.toml", "--check"),
         names="{d}/scene/broken.toml"),
    Case("scene file not UTF-8", ("run", "{d}/scene/latin1.toml", "--check"),
         names="{d}/scene/latin1.toml: is not a text file in UTF-8"),
    Case("scene file's Prony override", ("run", "{d}/scene/prony.toml", "--check"),
         names="{d}/scene/prony.toml"),
    Case("bad value in a materials file", ("run", "{d}/scene/bad-materials.toml", "--check"),
         names="{d}/scene/soft.toml"),
    Case("bad value in an indenter file", ("run", "{d}/scene/bad-indenter.toml", "--check"),
         names="{d}/scene/sharp.toml"),
    Case("two bars closer than their width", ("sweep", "2pt", "--spacings", "0.5", "2",
                                              "--check"), names="spacing 0.5"),
    Case("sweep of a key the scene lacks", ("sweep", "1pt", "--param", "materials.skin.muu",
                                            "--factors", "2", "--check"),
         names="--param materials.skin.muu"),
    Case("sweep to a negative modulus", ("sweep", "1pt", "--param", "materials.bone.E",
                                         "--factors", "1", "-1", "--check"),
         names="--param materials.bone.E --factors -1"),
    Case("sweep without what to sweep", ("sweep", "1pt", "--out", "{d}/sweep"),
         names="sweep: nothing to sweep"),
    Case("mesh size on the command line", ("mesh", "--min-size", "-1", "--out", "{d}/mesh"),
         names="--min-size -1"),
    Case("resume without a checkpoint", ("run", "1pt", "--resume", "--out", "{d}/empty",
                                         "--set", "section.mesh.min_size=0.4",
                                         "--set", "section.mesh.max_size=1.2", "--quiet"),
         names="--resume", slow=True),
    Case("Python override, misspelled key",
         python='ft.load_scene("1pt", {"protocol": {"dept": 0.5}})',
         names='overrides["protocol"]["dept"]'),
    Case("Python override, bad list of tables",
         python='ft.load_scene("1pt", {"indenters": [{"file": "cylinder", "radius": -5.0}]})',
         names='overrides["indenters"]'),
    Case("Python override string", python='ft.load_scene("1pt", ["model.subcutaneous=dry"])',
         names='override "model.subcutaneous=dry"'),
    # What works now, and used not to: these must pass the check.
    Case("list of tables, Python (works)", code=0, slow=True,
         python='ft.check(ft.load_scene("1pt", {"indenters": [{"file": "cylinder", '
         '"radius": 5.0}]}))'),
    Case("list of tables, --config (works)", ("run", "1pt", "--check", "--config",
                                              "{d}/config/cylinder.toml"), code=0, slow=True),
    Case("scene's relative paths, other cwd (works)", ("run", "{d}/scene/good.toml", "--check"),
         code=0, slow=True),
]


def fixtures(folder: Path) -> Path:
    """The files the cases name, in `folder`."""
    from fingertip_dolfinx.datafiles import find

    for name, text in FILES.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if text is None:  # the paper's materials with a negative bone modulus
            text = find("materials", "wu2004", "").read_text().replace("E = 17000.0", "E = -1.0")
        path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)
    return folder


def run_case(case: Case, folder: Path) -> tuple[int, str]:
    """(exit code, the first line of what it printed) of one case, run in this process."""
    import fingertip_dolfinx as ft
    from fingertip_dolfinx.cli import main

    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            if case.python:
                exec(case.python.replace("{d}", str(folder)), {"ft": ft})
                code = 0
            else:
                code = main([a.replace("{d}", str(folder)) for a in case.argv])
    except ft.InputError as error:
        return 2, str(error)
    except Exception:  # a traceback: the case fails
        return 1, traceback.format_exc().strip().splitlines()[-1]
    lines = [line for line in stderr.getvalue().splitlines() if line.strip()]
    if case.python and code == 0:
        lines = ["(passed)"]
    errors = [line for line in lines if "error:" in line]
    return code, (errors or lines or [""])[0]


def run_all(folder: Path, cases=CASES) -> list[tuple[Case, int, str, bool]]:
    """(case, exit code, first line, as expected) of each case, run from a working directory
    that is not the scene files' folder."""
    here = Path.cwd()
    os.chdir(folder / "empty")
    try:
        rows = []
        for case in cases:
            code, message = run_case(case, folder)
            names = case.names.replace("{d}", str(folder))
            ok = code == case.code and (names in message if case.code else "error" not in message)
            message = message.replace(str(folder), "{d}").replace(PACKAGE, "…/fingertip_dolfinx")
            rows.append((case, code, message, ok))
        return rows
    finally:
        os.chdir(here)


def table(rows) -> str:
    """The Markdown table of the cases."""
    out = ["| mistake | input | exit | message (first line) |", "| --- | --- | --- | --- |"]
    for case, code, message, ok in rows:
        given = (case.python or "fingertip " + " ".join(case.argv)).replace("|", "\\|")
        cell = message.replace("|", "\\|")
        out.append(f"| {case.mistake}{'' if ok else ' **(not as expected)**'} | "
                   f"`{given}` | {code} | {cell} |")
    return "\n".join(out) + "\n"


def write_between_markers(page: Path, text: str) -> None:
    content = page.read_text()
    head, _, rest = content.partition(START)
    _, _, tail = rest.partition(END)
    page.write_text(f"{head}{START}\n{text}{END}{tail}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--write", type=Path, metavar="PAGE",
                        help="put the table into PAGE between the markers")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = run_all(fixtures(Path(tmp)))
    text = table(rows)
    print(text)
    bad = [case.mistake for case, _, _, ok in rows if not ok]
    print(f"{len(rows) - len(bad)} of {len(rows)} cases as expected" +
          (f"; not: {', '.join(bad)}" if bad else ""), file=sys.stderr)
    if args.write:
        write_between_markers(args.write, text)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
