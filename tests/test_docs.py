"""The documentation's generated reference of scene keys against the validators themselves.

The reference (docs/_ext/scene_keys.py) lists the fields of the option classes; the validators
check each table's keys against their own `allowed` lists. Loading every built-in scene with
`check_keys` wrapped records what the validators accept, table by table; the reference must
list exactly those keys, so a key added to a validator but not to its class (or the other way
round) fails here.
"""

import importlib.util
from pathlib import Path

import pytest

from fingertip_dolfinx import loading, scene, validation
from fingertip_dolfinx.datafiles import builtin_dir

DOCS = Path(__file__).resolve().parent.parent / "docs"


def _reference():
    spec = importlib.util.spec_from_file_location("scene_keys", DOCS / "_ext" / "scene_keys.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: The scene file's table -> the reference's heading for it.
OPTION_TABLES = {"model": "[model]", "steps": "[steps]", "output": "[output]",
                 "accuracy": "[accuracy]", "harmonic": "[harmonic]"}


def _accepted_keys(monkeypatch) -> dict[str, set[str]]:
    """What the validators accept, per reference heading, over every built-in scene."""
    seen: dict[str, set[str]] = {}

    def recording(where, data, allowed, required=(), what="key"):
        allowed = list(allowed)
        for table, heading in OPTION_TABLES.items():
            if where.endswith(f": {table}"):
                seen.setdefault(heading, set()).update(allowed)
        if " (" in where and where.endswith(")"):  # a protocol: "...: protocol (kind)"
            kind = where.rsplit(" (", 1)[1][:-1]
            seen.setdefault(f'[protocol] kind = "{kind}"', set()).update(allowed)
        return validation.check_keys(where, data, allowed, required, what)

    monkeypatch.setattr(scene, "check_keys", recording)
    monkeypatch.setattr(loading, "check_keys", recording)
    for path in sorted(builtin_dir("scenes").glob("*.toml")):
        scene.load_scene(path.stem)
    scene.load_scene("vibrotactile", {"harmonic": {"state": "held"}})  # the section has none
    return seen


def test_the_key_reference_lists_exactly_what_the_validators_accept(monkeypatch):
    reference = _reference().keys_of_reference()
    accepted = _accepted_keys(monkeypatch)
    assert set(OPTION_TABLES.values()) <= set(accepted), "a table was never validated"
    for heading, keys in accepted.items():
        assert heading in reference, f"the reference has no table {heading}"
        assert reference[heading] == keys, (heading, reference[heading] ^ keys)


def test_the_key_reference_names_every_table_of_a_scene_file():
    page = (DOCS / "reference" / "keys.md").read_text()
    for table in scene.TABLES:
        assert f"`{table}`" in page, f"docs/reference/keys.md does not name `{table}`"


@pytest.mark.parametrize("heading", ["[model]", "[steps]", "[output]"])
def test_every_listed_key_of_an_option_table_has_a_row(heading):
    text = _reference().render()
    block = text.split(f"## `{heading}`", 1)[1].split("\n## ", 1)[0]
    for key in _reference().keys_of_reference()[heading]:
        assert f"| `{key}` |" in block
