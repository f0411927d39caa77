"""The layout shows the physics: every module imports only modules above it in the chain of
docs/DESIGN.md (geometry -> mesh -> materials -> ... -> runner -> studies), so data flows one
way and there are no import cycles. The test reads the chain from the document itself."""

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fingertip_dolfinx"
DESIGN = PACKAGE.parent / "docs" / "DESIGN.md"


def _chain() -> dict[str, int]:
    """Module -> its row in DESIGN.md's table (modules named in one row share it)."""
    text = DESIGN.read_text().split("## The chain of modules", 1)[1].split("\n## ", 1)[0]
    rank = {}
    for row, line in enumerate(r for r in text.splitlines() if r.startswith("| `")):
        for name in re.findall(r"`([a-z0-9_/]+)`", line.split("|")[1]):
            rank[name.rstrip("/")] = row
    return rank


def _imports(path: Path) -> set[str]:
    """The package modules `path` imports (relative imports, first component)."""
    names = set()
    depth = len(path.relative_to(PACKAGE).parts) - 1  # 1 in studies/, 2 in studies/problems/
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            if node.level <= depth:
                continue  # a study importing a module of studies/
            names.add((node.module or "").split(".")[0] or node.names[0].name)
    return names - {"__version__"}


def test_every_module_is_in_the_chain():
    rank = _chain()
    modules = {p.stem for p in PACKAGE.glob("*.py")} - {"__init__"}
    assert modules <= set(rank), f"not in docs/DESIGN.md: {sorted(modules - set(rank))}"


def test_modules_import_only_modules_above_them():
    rank = _chain()
    wrong = []
    for path in [*PACKAGE.glob("*.py"), *(PACKAGE / "studies").rglob("*.py")]:
        me = path.relative_to(PACKAGE).parts[0].removesuffix(".py")
        if me == "__init__":
            continue
        for name in _imports(path):
            if rank[name] > rank[me]:
                wrong.append(f"{path.relative_to(PACKAGE)} imports {name}")
    assert not wrong, wrong
