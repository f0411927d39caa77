"""The set-up recipe: the one install script shared by `make`, CI and the Docker image.

No Docker engine runs in CI, so the image is checked by what can be checked without one:
hadolint's rules, and that the image runs the same recipe that CI exercises on every run.
"""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCKERFILE = REPO / "docker" / "Dockerfile"


def instructions(path: Path) -> list[tuple[str, str]]:
    """(KEYWORD, arguments) of each Dockerfile instruction, continuation lines joined."""
    text = re.sub(r"\\\n", " ", path.read_text())
    rows = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            keyword, _, args = line.partition(" ")
            rows.append((keyword.upper(), args.strip()))
    return rows


def test_dockerfile_passes_hadolint():
    hadolint = shutil.which("hadolint", path=str(Path(sys.executable).parent)) or shutil.which(
        "hadolint"
    )
    if hadolint is None:
        pytest.skip("hadolint is not installed (it comes with the 'test' extra)")
    result = subprocess.run(
        [hadolint, "--failure-threshold", "warning", str(DOCKERFILE)],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_image_uses_the_ci_install_recipe_as_non_root_with_a_compiler():
    rows = instructions(DOCKERFILE)
    keywords = [k for k, _ in rows]
    base = rows[keywords.index("FROM")][1]
    major, minor = map(int, re.search(r"python:(\d+)\.(\d+)", base).groups())
    assert (major, minor) >= (3, 12), f"the DOLFINx wheel needs Python >= 3.12, image has {base}"

    runs = [args for k, args in rows if k == "RUN"]
    assert any("build-essential" in r or "gcc" in r for r in runs), "FFCx needs a C compiler"
    install = next(i for i, (k, a) in enumerate(rows) if k == "RUN" and "make install" in a)
    users = [i for i, (k, a) in enumerate(rows) if k == "USER" and a.split(":")[0] not in ("0", "root")]
    assert users and users[0] < install, "the install must run as the non-root user"

    makefile = (REPO / "Makefile").read_text()
    assert re.search(r"^install: \$\(STAMP\)", makefile, re.M)
    assert "bash scripts/install.sh" in makefile
    assert re.search(r"^test: \$\(STAMP\)", makefile, re.M), "CI's `make test` must run the recipe"
    assert "make test" in (REPO / ".ci" / "run").read_text()


def test_readme_documents_the_two_commands_and_the_container():
    readme = (REPO / "README.md").read_text()
    for command in ("make test", "docker build -f docker/Dockerfile", "docker run"):
        assert command in readme, f"README lacks `{command}`"


def test_install_script_says_clearly_when_there_is_no_python_312(tmp_path):
    # A PATH whose only python is too old, and no pyenv: the script must stop with a fix.
    fake = tmp_path / "bin"
    fake.mkdir()
    old = fake / "python3"
    old.write_text("#!/bin/sh\nexit 1\n")  # what `import sys; sys.exit(version < 3.12)` gives on 3.11
    old.chmod(0o755)
    for tool in ("bash", "dirname", "grep", "sort", "cat"):
        found = shutil.which(tool)
        if found:
            (fake / tool).symlink_to(found)
    env = {"PATH": str(fake), "HOME": str(tmp_path), "VENV": str(tmp_path / "venv")}
    result = subprocess.run(
        [str(fake / "bash"), str(REPO / "scripts" / "install.sh")],
        capture_output=True,
        text=True,
        env=env,
    )
    assert result.returncode == 1
    assert "no Python >= 3.12 found" in result.stderr
    assert "Fix:" in result.stderr
    assert not (tmp_path / "venv").exists()
