"""The Fast DDS profiles shipped for the manager (it announces itself often: fast discovery
by short-lived commands; a reader repairs a missed first message fast) and for the client
commands (the same repair): used unless the user chose a profile, only with Fast DDS, and
read by Fast DDS without an error."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from contextros.cli.ros_commands import use_packaged_profile

VARIABLES = (
    "FASTDDS_DEFAULT_PROFILES_FILE",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
    "RMW_IMPLEMENTATION",
)
PROFILES = ("manager_discovery.xml", "client_discovery.xml")


@pytest.fixture
def clean_env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    for name in VARIABLES:
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


def test_the_shipped_profile_is_used_by_default(clean_env: pytest.MonkeyPatch) -> None:
    use_packaged_profile("manager_discovery.xml")
    profile = Path(os.environ["FASTDDS_DEFAULT_PROFILES_FILE"])
    assert profile.is_file() and "<leaseAnnouncement>" in profile.read_text()
    use_packaged_profile("client_discovery.xml")  # the first one stays: it is set now
    assert Path(os.environ["FASTDDS_DEFAULT_PROFILES_FILE"]) == profile


def test_a_users_profile_is_kept(clean_env: pytest.MonkeyPatch) -> None:
    clean_env.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", "/etc/mine.xml")
    use_packaged_profile("client_discovery.xml")
    assert "FASTDDS_DEFAULT_PROFILES_FILE" not in os.environ


def test_other_middlewares_are_left_alone(clean_env: pytest.MonkeyPatch) -> None:
    clean_env.setenv("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
    use_packaged_profile("manager_discovery.xml")
    assert "FASTDDS_DEFAULT_PROFILES_FILE" not in os.environ


@pytest.mark.parametrize("name", PROFILES)
def test_fast_dds_reads_the_shipped_profile_without_an_error(
    name: str, clean_env: pytest.MonkeyPatch
) -> None:
    """Fast DDS ignores a profile it cannot parse, saying so only on stderr."""
    pytest.importorskip("rclpy")
    use_packaged_profile(name)
    probe = "import rclpy; rclpy.init(); rclpy.create_node('profile_probe'); print('created')"
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.stdout.strip() == "created", done.stderr
    assert "Error" not in done.stderr, done.stderr
