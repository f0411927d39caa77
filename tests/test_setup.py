"""The set-up recipe: the one install script shared by `make`, CI and the Docker image.

No Docker engine runs in CI, so the image is checked by what can be checked without one:
hadolint's rules, that the image runs the same recipe that CI exercises on every run, and the
facts a first build in a real engine showed to matter (what the build context leaves out,
off-screen OpenGL for VTK, MPICH under Docker's seccomp profile, who owns the source folder).
scripts/docker_check.sh builds and runs the image wherever an engine is reachable.
"""

import os
import re
import shlex
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
    users = [i for i, (k, a) in enumerate(rows)
             if k == "USER" and a.split(":")[0] not in ("0", "root")]
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
    # A missing host folder given to -v is created by the engine, owned by root: the image's
    # user cannot write it. The folder is made first, and the run writes as the caller.
    mounts = [m.start() for m in re.finditer(r'-v "\$PWD/results:', readme)]
    assert mounts, "README shows no run with a results folder"
    assert 0 <= readme.find("mkdir -p results") < mounts[0], "results/ is not created first"
    run = readme[mounts[0] - 200 : mounts[0]]
    assert '--user "$(id -u):$(id -g)"' in run, "the run does not write as the caller"


def dockerignore_excludes(relpath: str) -> bool:
    """Whether the root .dockerignore keeps RELPATH out of the build context: Docker's rules
    (a pattern matches the path or one of its parent folders, `**` spans folders, `*` does
    not cross a `/`, a later `!pattern` takes a path back, the last match wins)."""
    excluded = False
    for line in (REPO / ".dockerignore").read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        keep = line.startswith("!")
        pattern = line.lstrip("!").strip("/")
        regex = re.escape(pattern).replace(r"\*\*/", "(.*/)?").replace(r"\*\*", ".*")
        regex = regex.replace(r"\*", "[^/]*").replace(r"\?", "[^/]")
        parts = relpath.split("/")
        prefixes = ["/".join(parts[: i + 1]) for i in range(len(parts))]
        if any(re.fullmatch(regex, prefix) for prefix in prefixes):
            excluded = not keep
    return excluded


def test_build_context_leaves_out_git_and_local_state_and_keeps_the_source():
    # Only the root .dockerignore is read (docker/.dockerignore by no builder; BuildKit would
    # prefer docker/Dockerfile.dockerignore over the root file).
    assert not (REPO / "docker" / ".dockerignore").exists(), "docker/.dockerignore does nothing"
    assert not (REPO / "docker" / "Dockerfile.dockerignore").exists()
    for local in (".git", ".git/HEAD", ".venv/bin/python", "results/line-load/summary.json",
                  "fingertip_dolfinx/__pycache__/cli.cpython-312.pyc"):
        assert dockerignore_excludes(local), f"{local} would be copied into the image"
    needed = ["pyproject.toml", "README.md", "Makefile"] + [
        str(p.relative_to(REPO)) for top in ("fingertip_dolfinx", "scripts", "docker", "tests")
        for p in (REPO / top).rglob("*") if p.is_file() and "__pycache__" not in p.parts]
    assert not [p for p in needed if dockerignore_excludes(p)], "source left out of the image"


def apt_packages(rows) -> set[str]:
    runs = " ".join(args for k, args in rows if k == "RUN" and "apt-get install" in args)
    return set(re.findall(r"\b(lib[\w.+-]+|build-essential)\b", runs))


def test_image_gives_vtk_an_off_screen_opengl_that_this_vtk_loads():
    # No display in a container: VTK falls back to EGL, then OSMesa, and segfaults without
    # either. The package must provide the library the installed VTK wheel asks for.
    packages = apt_packages(instructions(DOCKERFILE))
    provides = {"libegl1": ("libvtkglad*.so*", b"libEGL.so.1"),
                "libosmesa6": ("libvtkRenderingOpenGL2*.so*", b"libOSMesa")}
    chosen = [p for p in provides if p in packages]
    assert chosen, f"no off-screen OpenGL (libegl1 or libosmesa6) among {sorted(packages)}"
    vtkmodules = pytest.importorskip("vtkmodules")
    folder = Path(vtkmodules.__file__).parent
    for package in chosen:
        pattern, soname = provides[package]
        libraries = list(folder.glob(pattern))
        assert any(soname in lib.read_bytes() for lib in libraries), (
            f"{package} provides {soname.decode()}, which this VTK does not load")


def test_image_turns_off_mpich_cross_memory_attach_that_docker_refuses():
    # MPICH (>= 5.0) copies between ranks with process_vm_readv, which Docker's default
    # seccomp profile refuses: the first MPI exchange in a container aborts.
    env = {}
    for keyword, args in instructions(DOCKERFILE):
        if keyword == "ENV":
            env.update(item.split("=", 1) for item in shlex.split(args) if "=" in item)
    assert env.get("MPIR_CVAR_CH4_CMA_ENABLE") == "0", "MPICH's CMA is not turned off"
    libmpi = sorted(Path(sys.prefix, "lib").glob("libmpi*.so*"))
    if libmpi:  # the variable's name is one this MPICH reads
        assert any(b"MPIR_CVAR_CH4_CMA_ENABLE" in lib.read_bytes() for lib in libmpi)


def test_source_folder_is_made_by_root_for_the_user_before_the_install():
    # The classic builder's WORKDIR creates a missing folder owned by root whatever USER says,
    # and the install run as the user then fails with Permission denied.
    rows = instructions(DOCKERFILE)
    keywords = [k for k, _ in rows]
    workdir = rows[keywords.index("WORKDIR")][1]
    user = next(i for i, (k, a) in enumerate(rows) if k == "USER" and a.split(":")[0] != "0")
    made = [i for i, (k, a) in enumerate(rows[:user]) if k == "RUN" and workdir in a
            and (re.search(r"install\s+-d\s+-o\s*(1000|fingertip)", a)
                 or re.search(r"chown\s+(-R\s+)?(1000|fingertip)", a))]
    assert made, f"{workdir} is not created for the user, as root, before USER"
    copies = [a for k, a in rows if k == "COPY"]
    assert all(a.startswith("--chown=") for a in copies), "COPY leaves root-owned files"


def test_docker_check_says_plainly_when_no_engine_is_reachable(tmp_path):
    script = REPO / "scripts" / "docker_check.sh"
    refusing = tmp_path / "docker"  # a client whose engine is not there
    refusing.write_text("#!/bin/sh\necho 'Cannot connect to the Docker daemon at "
                        "unix:///nowhere.sock' >&2\nexit 1\n")
    refusing.chmod(0o755)
    env = dict(os.environ, LOGS=str(tmp_path / "logs"))
    for docker, reason in (("no-such-docker-client", "no 'no-such-docker-client' command"),
                           (str(refusing), "Cannot connect to the Docker daemon")):
        for require, code in (("0", 0), ("1", 3)):
            result = subprocess.run(["bash", str(script)], capture_output=True, text=True,
                                    env=dict(env, DOCKER=docker, REQUIRE_DOCKER=require))
            assert result.returncode == code, result.stdout + result.stderr
            assert "skipped: no Docker engine" in result.stdout and reason in result.stdout


def test_install_script_says_clearly_when_there_is_no_python_312(tmp_path):
    # A PATH whose only python is too old, and no pyenv: the script must stop with a fix.
    fake = tmp_path / "bin"
    fake.mkdir()
    old = fake / "python3"
    # what `import sys; sys.exit(version < 3.12)` gives on 3.11
    old.write_text("#!/bin/sh\nexit 1\n")
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


def test_image_lets_a_rank_wait_for_a_form_another_rank_compiles():
    # Every new container starts with an empty form cache; ranks solving alone compile the
    # same forms at once and FFCx's default 10 s wait gives up long before a compile on a busy
    # machine ends, leaving the other rank waiting in a collective.
    runs = " ".join(a for k, a in instructions(DOCKERFILE) if k == "RUN")
    found = re.search(r"""\{\s*"timeout"\s*:\s*(\d+)\s*\}'?\s*>\s*(\S+)""", runs)
    assert found, "no DOLFINx JIT options file with a timeout"
    assert int(found.group(1)) >= 600, "a compile can take minutes: wait at least 10 min"
    assert found.group(2).endswith(".config/dolfinx/dolfinx_jit_options.json")


def test_the_3d_newton_forms_wait_for_a_compile_another_process_runs():
    # The same race outside the container (no JIT options file): the 3D acuity study's runs
    # side by side, one per rank, compile the same 3D Newton forms at once; those take minutes
    # (docs/benchmarks/measurements.md), so the wait must be at least 10 min, in the options
    # the forms are compiled with.
    from dolfinx.jit import get_options

    from fingertip_dolfinx.problem import JIT_OPTIONS_3D

    assert get_options(JIT_OPTIONS_3D)["timeout"] >= 600


def test_version_is_written_once_in_pyproject_and_read_without_an_install(monkeypatch):
    """`__version__` is pyproject.toml's version, from the installed distribution's metadata
    or, in a source tree that is not installed, from the tree's pyproject.toml: no second copy
    in the package to fall out of step."""
    import importlib.metadata
    import tomllib

    import fingertip_dolfinx as ft

    expected = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    copies = [p.name for p in (REPO / "fingertip_dolfinx").rglob("*.py")
              if re.search(r"__version__\s*=\s*['\"]", p.read_text())]
    assert not copies, f"a version written in the package: {copies}"
    assert ft.__version__ == expected

    def not_installed(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", not_installed)
    monkeypatch.delitem(ft.__dict__, "__version__")
    assert ft.__version__ == expected
