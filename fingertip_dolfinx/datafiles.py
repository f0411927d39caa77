"""Data files: the built-in ones shipped inside the package, and the user's own TOML files.

Built-in files live in `fingertip_dolfinx/data/<kind>/` (`scenes`, `sections`, `indenters`,
`materials`, `receptors`) and are found with `importlib.resources`, so a non-editable install
(a wheel in site-packages) finds them as well as a source checkout does. A file is named either
by the stem of a built-in one (`line-load`) or by a path (`./my-scene.toml`).
"""

from __future__ import annotations

import importlib.metadata
import tomllib
from importlib.resources import files
from pathlib import Path

from .errors import InputError

KINDS = ("scenes", "sections", "indenters", "materials", "receptors")


def builtin_dir(kind: str) -> Path:
    """The folder of the built-in files of one kind (a real folder: the package is never
    imported from a zip archive, its DOLFINx dependency cannot be)."""
    if kind not in KINDS:
        raise ValueError(f"unknown kind of data file {kind!r}; one of {KINDS}")
    return Path(str(files("fingertip_dolfinx") / "data" / kind))


def builtin_names(kind: str) -> list[str]:
    return sorted(p.stem for p in builtin_dir(kind).glob("*.toml"))


def find(kind: str, source: str | Path, what: str) -> Path:
    """The file named by `source`: a path to a TOML file, or the stem of a built-in one.

    `what` names the input in the error ("scene", "section", ...).
    """
    path = Path(source)
    if path.suffix != ".toml" and not path.is_file():  # a folder named like one is not it
        path = builtin_dir(kind) / f"{source}.toml"
    if not path.is_file():
        raise InputError(
            str(source), f"no such {what} file (no such file: {path}).",
            f"give a path to a .toml file, or a built-in {what}: "
            f"{', '.join(builtin_names(kind))} (in {builtin_dir(kind)}).")
    return path


def read_toml(path: str | Path) -> dict:
    """The tables of a TOML file; a syntax error names the file and the line."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as error:
        raise InputError(str(path), f"is not valid TOML: {error}.", "fix the syntax.") from None
    except UnicodeDecodeError as error:  # TOML is UTF-8: a binary file, or another encoding
        raise InputError(str(path), f"is not a text file in UTF-8 ({error.reason} at byte "
                         f"{error.start}).", "give a TOML file (UTF-8 text); save it as "
                         "UTF-8 if it was written in another encoding.") from None
    except IsADirectoryError:
        raise InputError(str(path), "is a folder, not a file.", "give a .toml file.") from None


def package_version() -> str:
    """The version pyproject.toml gives (its one place): the installed distribution's, or in
    a source tree that is not installed, read from the tree's pyproject.toml."""
    try:
        return importlib.metadata.version("fingertip-dolfinx")
    except importlib.metadata.PackageNotFoundError:
        try:
            with (Path(__file__).resolve().parents[1] / "pyproject.toml").open("rb") as f:
                return tomllib.load(f)["project"]["version"]
        except (OSError, KeyError, tomllib.TOMLDecodeError):
            return "0+unknown"
