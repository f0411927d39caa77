"""The layout shows the physics: every module imports only modules above it in the chain of
docs/DESIGN.md (geometry -> mesh -> materials -> ... -> runner -> studies), so data flows one
way and there are no import cycles. The test reads the chain from the document itself."""

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fingertip_dolfinx"
DESIGN = PACKAGE.parent / "docs" / "DESIGN.md"
#: Subpackages whose modules have rows of their own in the chain (`stepping.options`, ...).
SUBPACKAGES = ("stepping",)


def _chain() -> dict[str, int]:
    """Module -> its row in DESIGN.md's table (modules named in one row share it)."""
    text = DESIGN.read_text().split("## The chain of modules", 1)[1].split("\n## ", 1)[0]
    rank = {}
    for row, line in enumerate(r for r in text.splitlines() if r.startswith("| `")):
        for name in re.findall(r"`([a-z0-9_/.]+)`", line.split("|")[1]):
            rank[name.rstrip("/")] = row
    for package in SUBPACKAGES:  # `from .stepping import X` may reach any of its modules
        rank[package] = max(r for name, r in rank.items() if name.startswith(package + "."))
    return rank


def _row_name(parts: list[str]) -> str:
    """The chain's name of a package module given by its path parts: "scene",
    "stepping.options" (a subpackage's modules have rows of their own), "studies" (one row)."""
    if parts[0] in SUBPACKAGES and len(parts) > 1:
        return f"{parts[0]}.{parts[1]}"
    return parts[0]


def _modules() -> list[Path]:
    return [*PACKAGE.glob("*.py"), *(PACKAGE / "studies").glob("*.py"),
            *(p for package in SUBPACKAGES for p in (PACKAGE / package).glob("*.py"))]


def _imports(path: Path) -> set[str]:
    """The package modules `path` imports (relative imports), by their names in the chain."""
    package = list(path.relative_to(PACKAGE).parts[:-1])
    names = set()

    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[: len(package) - (node.level - 1)]
            if node.module:
                names.add(_row_name([*base, *node.module.split(".")]))
            else:  # `from . import x`
                names.update(_row_name([*base, alias.name]) for alias in node.names)
    return names - {"__version__"}


def test_every_module_is_in_the_chain():
    rank = _chain()
    modules = {_row_name(list(p.relative_to(PACKAGE).with_suffix("").parts))
               for p in _modules() if p.stem != "__init__"}
    assert modules <= set(rank), f"not in docs/DESIGN.md: {sorted(modules - set(rank))}"


def test_modules_import_only_modules_above_them():
    rank = _chain()
    wrong = []
    for path in _modules():
        me = _row_name(list(path.relative_to(PACKAGE).with_suffix("").parts))
        if me == "__init__" or me.endswith(".__init__"):
            continue  # the package roots: names on first use, no imports to check
        for name in _imports(path):
            if rank[name] > rank[me]:
                wrong.append(f"{path.relative_to(PACKAGE)} imports {name}")
    assert not wrong, wrong
