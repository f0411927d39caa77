"""Every function of the package fits on a screen: at most 60 lines from its `def` to its last
line (docstring included, decorators not), unless the line just above it (above its first
decorator, if it has any) gives the reason: a comment `# long: <reason>` (docs/DESIGN.md,
"Function length")."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fingertip_dolfinx"
MAX_LINES = 60
MARKER = "# long:"

#: Functions over the limit in modules being split right now (being split: to be removed from
#: this list when the split is merged).
BEING_SPLIT = {
}


def _functions(tree: ast.AST, prefix: str = ""):
    """(qualified name, node) of every function and method in `tree`, nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield prefix + node.name, node
            yield from _functions(node, f"{prefix}{node.name}.")
        elif isinstance(node, ast.ClassDef):
            yield from _functions(node, f"{prefix}{node.name}.")
        else:
            yield from _functions(node, prefix)


def too_long(source: str, allowed: set[str] = frozenset()) -> list[tuple[str, int]]:
    """(name, lines) of the functions in `source` over MAX_LINES without a `# long:` reason on
    the line above them, except the names in `allowed`."""
    lines = source.splitlines()
    found = []
    for name, node in _functions(ast.parse(source)):
        length = node.end_lineno - node.lineno + 1
        first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
        above = lines[first - 2].strip() if first >= 2 else ""
        if length > MAX_LINES and not above.startswith(MARKER) and name not in allowed:
            found.append((name, length))
    return found


def test_no_function_is_longer_than_a_screen_without_a_reason():
    wrong = []
    for path in sorted(PACKAGE.rglob("*.py")):
        allowed = BEING_SPLIT.get(str(path.relative_to(PACKAGE)), set())
        wrong += [f"{path.relative_to(PACKAGE)}: {name} ({n} lines)"
                  for name, n in too_long(path.read_text(), allowed)]
    assert not wrong, f"over {MAX_LINES} lines (split, or give `{MARKER} <reason>`): {wrong}"


def _function(name: str, lines: int, above: str = "", decorator: str = "") -> str:
    """Source of a function `lines` long, with the line `above` and a `decorator` (if any)."""
    body = [f"    x{i} = {i}" for i in range(lines - 2)]
    head = [line for line in (above, decorator) if line]
    return "\n".join(["", *head, f"def {name}():", *body, "    return 0", ""])


def test_the_check_counts_lines_and_reads_the_reason():
    assert too_long(_function("f", 60)) == []
    assert too_long(_function("f", 61)) == [("f", 61)]
    assert too_long(_function("f", 61, above="# long: one table, row by row")) == []
    assert too_long(_function("f", 61, above="# long: x", decorator="@staticmethod")) == []
    assert too_long(_function("f", 61, above="# a comment that gives no reason")) == [("f", 61)]
    assert too_long(_function("f", 61), allowed={"f"}) == []
    method = "class A:\n" + "\n".join("    " + line for line in _function("g", 61).splitlines())
    assert too_long(method) == [("A.g", 61)]
