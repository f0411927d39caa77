"""The demos (demos/*.py) run end to end at their coarse settings, as scripts (slow: CI
executes them in the documentation build).

Each runs as a script, as a user would run it, into a temporary directory, and must exit 0
and write its figure. The demos print their own numbers; their physics is checked where the
model is (the rest of the suite), not here.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DEMOS = {
    "demo_line_load.py": "line_load.png",
    "demo_permeability_sweep.py": "permeability_sweep.png",
    "demo_custom_indenter.py": "custom_indenter.png",
}


# CI executes every demo at its coarse settings when it builds the documentation (myst-nb,
# errors raised): here they run on demand, with `make test-slow`.
@pytest.mark.slow
@pytest.mark.parametrize("demo", sorted(DEMOS))
def test_demo_runs_coarse_and_writes_its_figure(demo, tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, FINGERTIP_DEMO_COARSE="1", FINGERTIP_DEMO_OUT=str(out),
               MPLBACKEND="Agg", OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1",
               PYTHONPATH=os.pathsep.join(filter(None, [str(REPO),
                                                        os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, str(REPO / "demos" / demo), "--coarse"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900,
                            check=False)
    assert result.returncode == 0, (result.stdout[-3000:] + result.stderr[-3000:])
    figure = out / DEMOS[demo]
    assert figure.is_file() and figure.stat().st_size > 10_000, result.stdout[-2000:]


def test_every_demo_is_a_percent_script_listed_in_the_readme():
    readme = (REPO / "demos" / "README.md").read_text()
    found = sorted(p.name for p in (REPO / "demos").glob("demo_*.py"))
    assert found == sorted(DEMOS)
    for name in found:
        text = (REPO / "demos" / name).read_text()
        assert "format_name: percent" in text and "# %% [markdown]" in text, name
        assert "--coarse" in text and "FINGERTIP_DEMO_OUT" in text, name
        assert name in readme, f"demos/README.md does not list {name}"
