"""The layout shows the physics: every module imports only modules above it in the chain of
docs/DESIGN.md, so data flows one way. Modules in one row may import each other, but not in
a circle. Relative, absolute and deferred (inside a function) imports all count. The test
reads the chain from the document itself, so the document cannot drift from the code."""

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fingertip_dolfinx"
DESIGN = PACKAGE.parent / "docs" / "DESIGN.md"


def module_name(path: Path, package: Path) -> str:
    """`geometry/mesh.py` -> 'geometry.mesh'; a package's `__init__.py` -> the package."""
    parts = list(path.relative_to(package).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules(package: Path) -> dict[str, Path]:
    return {module_name(p, package): p for p in package.rglob("*.py")}


def chain(text: str) -> dict[str, int]:
    """Module (or package, written `name/`) -> its row in the chain table of DESIGN.md."""
    table = text.split("## The chain of modules", 1)[1].split("\n## ", 1)[0]
    rank = {}
    for row, line in enumerate(r for r in table.splitlines() if r.startswith("| `")):
        for name in re.findall(r"`([a-z0-9_./]+)`", line.split("|")[1]):
            rank[name.rstrip("/")] = row
    return rank


def rank_of(module: str, rank: dict[str, int]) -> int | None:
    """The row of a module: its own, or that of the nearest package written as a row."""
    parts = module.split(".")
    for i in range(len(parts), 0, -1):
        if ".".join(parts[:i]) in rank:
            return rank[".".join(parts[:i])]
    return None


def imports(path: Path, package: Path) -> set[str]:
    """The package's modules a file imports, by dotted name ('' is the package root)."""
    root, known = package.name, modules(package)
    here = module_name(path, package).split(".") if module_name(path, package) else []
    base = here if path.name == "__init__.py" else here[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
            names = []
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = base[: len(base) - node.level + 1] + (node.module or "").split(".")
                targets = [".".join([root, *filter(None, parts)])]
            else:
                targets = [node.module or ""]
            names = [a.name for a in node.names]
        else:
            continue
        for target in targets:
            if target.split(".")[0] != root:
                continue
            inner = target.removeprefix(root).lstrip(".")
            # `from ..physics import materials` imports the module physics.materials
            subs = {f"{inner}.{n}".lstrip(".") for n in names} & set(known)
            found |= subs or {inner}
    return found


def back_arrows(package: Path, rank: dict[str, int]) -> list[str]:
    wrong = []
    for me, path in modules(package).items():
        if path.name == "__init__.py":
            continue  # a package re-exports its own modules
        for name in imports(path, package):
            if name in ("", "__version__"):
                wrong.append(f"{me} imports the package root: import the module it needs")
            elif rank_of(name, rank) > rank_of(me, rank):
                wrong.append(f"{me} imports {name}, which is further down the chain")
    return wrong


def circles(package: Path) -> list[list[str]]:
    """Import cycles among the package's modules (depth-first search)."""
    known = modules(package)
    graph = {m: {n for n in imports(p, package) if n in known and n != m}
             for m, p in known.items() if p.name != "__init__.py"}
    found, state = [], {}

    def visit(node, stack):
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                found.append([*stack[stack.index(nxt):], nxt])
            elif nxt not in state:
                visit(nxt, [*stack, nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    return found


def test_every_module_is_in_the_chain():
    rank = chain(DESIGN.read_text())
    missing = sorted(m for m, path in modules(PACKAGE).items()
                     if path.name != "__init__.py" and rank_of(m, rank) is None)
    assert not missing, f"not in docs/DESIGN.md's chain: {missing}"


def test_modules_import_only_modules_above_them():
    wrong = back_arrows(PACKAGE, chain(DESIGN.read_text()))
    assert not wrong, wrong


def test_no_import_circles():
    assert not circles(PACKAGE), circles(PACKAGE)


# The checks must be able to fail: a toy package with each kind of defect.
TOY_CHAIN = "## The chain of modules\n| `low` | |\n| `mid/` | |\n| `high` | |\n"


def toy(tmp_path: Path, files: dict[str, str]) -> Path:
    package = tmp_path / "toy"
    for name, text in {"__init__.py": "", "mid/__init__.py": "", **files}.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    return package


def test_the_check_sees_back_arrows_of_every_form(tmp_path):
    package = toy(tmp_path, {
        "low.py": "def f():\n    import toy.high\n",  # absolute, deferred
        "mid/a.py": "from ..high import x\n",  # relative, two levels
        "mid/b.py": "from toy import high\n",  # the module named as an imported name
        "high.py": "from .mid import a\nimport toy\n",  # downward, then the package root
    })
    wrong = back_arrows(package, chain(TOY_CHAIN))
    assert len(wrong) == 4, wrong


def test_the_check_sees_a_circle_within_a_row(tmp_path):
    package = toy(tmp_path, {"low.py": "", "high.py": "",
                             "mid/a.py": "from .b import x\n", "mid/b.py": "from . import a\n"})
    assert not back_arrows(package, chain(TOY_CHAIN))
    assert circles(package) == [["mid.a", "mid.b", "mid.a"]]
