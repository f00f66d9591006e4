"""ContextROS as a user installs it, outside the clone: the wheel built from this checkout
(reused while its inputs are unchanged), a fresh venv holding only it and the ROS wheels,
and a C++ project of the user's that finds the installed CMake package.

The builds are cached under build/install/ keyed by a hash of what goes into them, so only
the first run of a checkout (or one after a change to the package) pays for them.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import pytest

from contextros import __version__
from tests.ros.processes import reserve_domain_id

REPOSITORY = Path(__file__).resolve().parents[2]
CACHE = REPOSITORY / "build" / "install"
# What the wheel is built from.
WHEEL_INPUTS = ("packaging/wheel", "pyproject.toml", "src/contextros", "cpp", "interfaces")
# The packages a C++ user adds to find_package() ROS 2 from the wheels (the `cpp` extra).
EXTRAS = "ros,cpp"

_worker = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
DOMAIN_ID = reserve_domain_id(90 + _worker)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if "tests/install/" in str(item.path).replace(os.sep, "/"):
            item.add_marker(pytest.mark.ros)


def inputs_hash(paths: tuple[str, ...]) -> str:
    """A hash of the files under `paths` (tracked or not, minus what git ignores)."""
    listed = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "--", *paths],
        cwd=REPOSITORY,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    digest = hashlib.sha256()
    for name in sorted(listed):
        file = REPOSITORY / name
        if file.is_file():
            digest.update(name.encode() + b"\0" + file.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def user_environment(
    venv: Path | None = None, *, with_python: bool = False, **extra: str
) -> dict[str, str]:
    """A user's shell: nothing of this checkout's venv, build or ROS set-up leaks in;
    `with_python`: the machine's Python (this venv's base interpreter) first on PATH."""
    leaks = (
        "PYTHONPATH",
        "PYTHONHOME",
        "VIRTUAL_ENV",
        "LD_LIBRARY_PATH",
        "AMENT_PREFIX_PATH",
        "CMAKE_PREFIX_PATH",
        "COLCON_PREFIX_PATH",
        "RMW_IMPLEMENTATION",
        "_ROS_WHEELS_BOOTSTRAP_COMPLETE",
    )
    environment = {k: v for k, v in os.environ.items() if k not in leaks}
    path = ["/usr/local/bin", "/usr/bin", "/bin"]
    if venv is not None:
        path.insert(0, str(venv / "bin"))
    if with_python:
        path.insert(0, str(Path(getattr(sys, "_base_executable", sys.executable)).parent))
    if not shutil.which("cmake", path=os.pathsep.join(path)):  # the Makefile's fallback
        path.append(str(Path(sys.executable).parent))
    environment.update(
        PATH=os.pathsep.join(path),
        ROS_DOMAIN_ID=str(DOMAIN_ID),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        **extra,
    )
    return environment


def run(argv: list[str], *, env: Mapping[str, str], cwd: Path, what: str) -> str:
    done = subprocess.run(argv, env=dict(env), cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        raise AssertionError(
            f"{what} failed ({done.returncode}): {' '.join(argv)}\n{done.stdout[-3000:]}"
            f"\n{done.stderr[-3000:]}"
        )
    return done.stdout


@contextmanager
def exclusive(name: str) -> Iterator[None]:
    """Held by one test process at a time (two xdist workers may want the same build)."""
    CACHE.mkdir(parents=True, exist_ok=True)
    with open(CACHE / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


@pytest.fixture(scope="session")
def wheel() -> Iterator[Path]:
    """The platform wheel of this checkout, built with the dev venv's build tools."""
    with exclusive("wheel"):
        yield _wheel()


def _wheel() -> Path:
    directory = CACHE / f"wheel-{inputs_hash(WHEEL_INPUTS)}"
    built = sorted(directory.glob("contextros-*.whl"))
    if not built:
        shutil.rmtree(directory, ignore_errors=True)
        environment = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}")
        run(
            [
                sys.executable,
                "-m",
                "pip",
                "wheel",
                "--no-build-isolation",
                "--no-deps",
                "--quiet",
                "--wheel-dir",
                str(directory),
                str(REPOSITORY),
            ],
            env=environment,
            cwd=REPOSITORY,
            what="building the wheel",
        )
        built = sorted(directory.glob("contextros-*.whl"))
    assert len(built) == 1, built
    return built[0]


def install_commands(name: str) -> str:
    """The commands of the ```sh <name> block of docs/install.md, as a user copies them."""
    text = (REPOSITORY / "docs" / "install.md").read_text()
    blocks = re.findall(r"^```sh " + re.escape(name) + r"\n(.*?)^```$", text, re.M | re.S)
    assert len(blocks) == 1, f"docs/install.md has {len(blocks)} ```sh {name} blocks"
    return str(blocks[0])


def run_commands(commands: str, *, env: Mapping[str, str], cwd: Path, what: str) -> str:
    """Run shell commands as a user pastes them (bash, stopping at the first failure)."""
    return run(["bash", "-eo", "pipefail", "-c", commands], env=env, cwd=cwd, what=what)


@pytest.fixture(scope="session")
def user_venv(wheel: Path) -> Iterator[Path]:
    """A fresh venv with only the wheel and the ROS wheels it asks for, made by docs/install.md's
    commands, as written, with the machine's Python (not this checkout's venv)."""
    with exclusive("venv"):
        yield _user_venv(wheel)


def _user_venv(wheel: Path) -> Path:
    home = CACHE / f"user-{wheel.parent.name.removeprefix('wheel-')}"
    venv = home / "contextros-venv"
    if not (home / ".complete").exists():
        shutil.rmtree(home, ignore_errors=True)
        home.mkdir(parents=True)
        commands = re.sub(r"^WHEEL=\S+", f"WHEEL={wheel}", install_commands("wheel"), flags=re.M)
        assert str(wheel) in commands, "the wheel block no longer sets WHEEL=..."
        output = run_commands(
            commands,
            env=user_environment(with_python=True),
            cwd=home,
            what="docs/install.md, wheel",
        )
        lines = output.splitlines()
        assert lines[-2:] == [f"contextros {__version__}", str(venv)], output  # --cmake-prefix
        (home / ".complete").touch()
    return venv


@pytest.fixture(scope="session")
def cpp_package(user_venv: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """examples/cpp_package built as a user's own CMake project against the installed wheel,
    by docs/install.md's commands: `find_package(contextros CONFIG REQUIRED)` with the prefix
    `contextros --cmake-prefix` prints, nothing else."""
    user = tmp_path_factory.mktemp("user")
    shutil.copytree(REPOSITORY / "examples" / "cpp_package", user / "examples" / "cpp_package")
    run_commands(
        f". {user_venv}/bin/activate\n" + install_commands("wheel-cpp"),
        env=user_environment(),
        cwd=user,
        what="docs/install.md, wheel-cpp",
    )
    return user / "build" / "greeter" / "greeter"
