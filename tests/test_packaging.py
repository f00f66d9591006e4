"""One version number and one list of dependencies, wherever a package manager reads them."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from contextros import __version__

tomllib = pytest.importorskip("tomllib")  # Python >= 3.11

REPOSITORY = Path(__file__).resolve().parent.parent
PACKAGE_XMLS = [
    "interfaces/contextros_interfaces/package.xml",
    "cpp/package.xml",
    "packaging/colcon/contextros/package.xml",
]


def test_every_package_xml_has_the_version_of_the_python_package() -> None:
    for name in PACKAGE_XMLS:
        version = re.search(r"<version>(.*?)</version>", (REPOSITORY / name).read_text())
        assert version is not None and version.group(1) == __version__, name


def test_the_colcon_requirements_are_pyprojects() -> None:
    """packaging/colcon/requirements.txt: the ROS wheels and build tools pinned as the extras
    pin them, and the package's own dependencies."""
    project = tomllib.loads((REPOSITORY / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    wanted = {*project["dependencies"], *extras["ros"], *extras["cpp"]}
    wanted |= {r for r in extras["ros-build"] if "gtest" not in r}  # no C++ tests in colcon
    lines = (REPOSITORY / "packaging/colcon/requirements.txt").read_text().splitlines()
    listed = {line for line in lines if line and not line.startswith("#")}
    assert wanted <= listed, wanted - listed
