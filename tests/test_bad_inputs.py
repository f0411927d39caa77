"""The mistakes of scripts/bad_inputs.py (the table in docs/guide/troubleshooting.md): each
ends with its exit code and one line that names where the bad value came from (`--set`,
`--config FILE`, the Python override, the scene, materials or indenter file). The cases that
only validate run by default (no mesh is built: seconds); those that build a mesh or a
problem are slow."""

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bad_inputs.py"


def _script():
    spec = importlib.util.spec_from_file_location("bad_inputs", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["bad_inputs"] = module  # its dataclass looks its module up
    spec.loader.exec_module(module)
    return module


BAD = _script()


def _check(cases, tmp_path):
    rows = BAD.run_all(BAD.fixtures(tmp_path), cases)
    wrong = [(case.mistake, code, message) for case, code, message, ok in rows if not ok]
    assert not wrong, wrong
    for _case, code, message, _ in rows:
        assert "\n" not in message and (code == 0 or "Fix" in message or "error" in message)


def test_at_least_thirty_mistakes_are_tried():
    assert sum(case.code != 0 for case in BAD.CASES) >= 30


def test_every_validation_mistake_names_its_source_in_one_line(tmp_path):
    _check([case for case in BAD.CASES if not case.slow], tmp_path)


@pytest.mark.slow
def test_the_mistakes_found_on_the_mesh_and_the_fixed_classes(tmp_path):
    _check([case for case in BAD.CASES if case.slow], tmp_path)
