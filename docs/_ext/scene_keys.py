"""Sphinx extension: the reference of scene keys, generated from the option classes themselves.

Each table of a scene file is read into a frozen dataclass whose fields are exactly the keys
that table accepts (`scene._options` checks unknown keys against them), so a reference built
from `dataclasses.fields` cannot drift from the validators. A field's description is its `#:`
comment in the source (the comment Sphinx's autodoc reads too); the class docstring introduces
the table. `reference/keys.md` includes the generated `reference/_keys.md`; `reference/api.md`
includes `reference/_api.md`, one entry per public name of the package.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import textwrap
from pathlib import Path


def tables():
    """(TOML table, option class, note) for every table whose keys are a dataclass's fields."""
    from fingertip_dolfinx import harmonic_options, loading, model, scene, stepping
    from fingertip_dolfinx.geometry import fingertip3d, indenters, section

    rows = [
        ("[model]", model.ModelOptions, ""),
        ("[steps]", stepping.StepOptions, ""),
        ("[output]", scene.Outputs, ""),
        ("[accuracy]", scene.Accuracy, ""),
        ("[harmonic]", harmonic_options.HarmonicOptions, ""),
        ("[section.mesh]", section.MeshOptions, ""),
        ("[section] (3D: `dimension = 3`)", fingertip3d.Fingertip3D,
         "`section` is the 2D cross-section carried along z; `name` is set from the file."),
    ]
    for kind, cls in loading.KINDS.items():
        rows.append((f'[protocol] kind = "{kind}"', cls, ""))
    for shape, cls in indenters.SHAPES.items():
        rows.append((f'[[indenters]] shape = "{shape}"', cls, ""))
    return rows


def field_comments(cls) -> dict[str, str]:
    """The `#:` comment lines just above each field of a dataclass, joined (or the comment
    on the field's own line), over the class and the classes it inherits fields from."""
    comments: dict[str, str] = {}
    for base in reversed(cls.__mro__):
        if dataclasses.is_dataclass(base):
            comments |= _own_field_comments(base)
    return comments


def _own_field_comments(cls) -> dict[str, str]:
    try:
        lines, _ = inspect.getsourcelines(cls)
    except (OSError, TypeError):
        return {}
    source = textwrap.dedent("".join(lines))
    comments, pending = {}, []
    for line in source.splitlines():
        stripped = line.strip()
        if stripped.startswith("#:"):
            pending.append(stripped[2:].strip())
            continue
        name = stripped.split(":", 1)[0].strip()
        if pending and name.isidentifier() and ":" in stripped:
            comments[name] = " ".join(pending)
        pending = []
    # a trailing comment on the field's own line also counts
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            text = source.splitlines()[node.lineno - 1]
            if "#" in text and node.target.id not in comments:
                comments[node.target.id] = text.split("#", 1)[1].strip()
    return comments


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return "required"
    if isinstance(value, str):
        return f'`"{value}"`' if value else '`""`'
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if value is None:
        return "(none)"
    if dataclasses.is_dataclass(value):
        return "(see its table)"
    return f"`{value!r}`".replace("(", "[").replace(")", "]") if isinstance(value, tuple) \
        else f"`{value!r}`"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _intro(doc: str) -> str:
    """A docstring up to its first numpy section (``Parameters`` over a line of dashes): the
    table below lists the keys, so the section would say it twice."""
    lines = doc.splitlines()
    for i in range(len(lines) - 1):
        if lines[i].strip() and set(lines[i + 1].strip()) == {"-"}:
            return "\n".join(lines[:i]).strip()
    return doc


def render() -> str:
    out = []
    for table, cls, note in tables():
        doc = _intro(inspect.getdoc(cls) or "")
        comments = field_comments(cls)
        out += [f"## `{table}`", "", f"Read into `{cls.__module__}.{cls.__qualname__}`.", ""]
        if doc:
            out += [doc, ""]
        if note:
            out += [note, ""]
        out += ["| key | type | default | description |", "| --- | --- | --- | --- |"]
        for f in dataclasses.fields(cls):
            if not f.init:
                continue
            out.append(f"| `{f.name}` | `{_cell(str(f.type))}` | {_cell(_default(f))} | "
                       f"{_cell(comments.get(f.name, ''))} |")
        out.append("")
    return "\n".join(out)


def keys_of_reference() -> dict[str, set[str]]:
    """Table -> the keys this reference lists (what the tests compare with the validators)."""
    return {table: {f.name for f in dataclasses.fields(cls) if f.init}
            for table, cls, _ in tables()}




# --- the API reference: every public name of `fingertip_dolfinx` (its `_API` table) ----------

#: Headings of the API page, by the module that defines a name.
API_GROUPS = {
    "Scenes and runs": ("scene", "routes", "runner", "result", "studies.adaptivity"),
    "Materials": ("physics.tissues", "physics.materials"),
    "Geometry, meshes, indenters and protocols": ("geometry.section", "geometry.mesh",
                                                   "geometry.fingertip3d", "geometry.mesh3d",
                                                   "geometry.indenters", "loading"),
    "Model, problem and solver": ("model", "problem", "stepping"),
    "Receptors and afferents": ("afferents.receptors",),
    "Errors": ("errors",),
}


def _inherits_from_the_package(cls: type) -> bool:
    return any(base.__module__.startswith("fingertip_dolfinx") for base in cls.__mro__[1:])


def render_api() -> str:
    import fingertip_dolfinx as ft

    by_module: dict[str, list[str]] = {}
    for name, module in ft._API.items():
        by_module.setdefault(module, []).append(name)
    grouped = {m for modules in API_GROUPS.values() for m in modules}
    others = sorted(set(by_module) - grouped)
    out = []
    for title, modules in (*API_GROUPS.items(), ("Other", tuple(others))):
        present = [m for m in modules if m in by_module]
        if not present:
            continue
        out += [f"## {title}", "", "```{eval-rst}"]
        for module in present:
            for name in sorted(by_module[module]):
                obj = getattr(ft, name)
                kind = ("autoclass" if isinstance(obj, type) else
                        "autofunction" if callable(obj) else "autodata")
                out.append(f".. {kind}:: fingertip_dolfinx.{module}.{name}")
                if kind == "autoclass":
                    out.append("   :members:")
                    if _inherits_from_the_package(obj):  # e.g. the state bookkeeping
                        out.append("   :inherited-members:")
                out.append("")
        out += ["```", ""]
    return "\n".join(out)


def escape_docstring(app, what, name, obj, options, lines) -> None:
    """The docstrings are plain text with maths like |x| and a*b: not reStructuredText
    markup, so `|` and `*` are escaped before docutils reads them."""
    for i, line in enumerate(lines):
        lines[i] = line.replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*")


def _write(app) -> None:
    for name, text in (("_keys.md", render()), ("_api.md", render_api())):
        target = Path(app.srcdir) / "reference" / name
        if not target.exists() or target.read_text() != text:
            target.write_text(text)


def setup(app):
    app.setup_extension("sphinx.ext.autodoc")
    app.connect("builder-inited", _write)
    app.connect("autodoc-process-docstring", escape_docstring)
    return {"version": "1", "parallel_read_safe": True}
