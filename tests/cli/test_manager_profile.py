"""`contextros manager` announces itself often (fast discovery by short-lived commands),
never overriding a Fast DDS profile the user chose, and only with Fast DDS."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from contextros.cli.ros_commands import _announce_often

VARIABLES = (
    "FASTDDS_DEFAULT_PROFILES_FILE",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
    "RMW_IMPLEMENTATION",
)


@pytest.fixture
def clean_env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    for name in VARIABLES:
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


def test_the_shipped_profile_is_used_by_default(clean_env: pytest.MonkeyPatch) -> None:
    _announce_often()
    profile = Path(os.environ["FASTDDS_DEFAULT_PROFILES_FILE"])
    assert profile.is_file() and "<leaseAnnouncement>" in profile.read_text()


def test_a_users_profile_is_kept(clean_env: pytest.MonkeyPatch) -> None:
    clean_env.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", "/etc/mine.xml")
    _announce_often()
    assert "FASTDDS_DEFAULT_PROFILES_FILE" not in os.environ


def test_other_middlewares_are_left_alone(clean_env: pytest.MonkeyPatch) -> None:
    clean_env.setenv("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
    _announce_often()
    assert "FASTDDS_DEFAULT_PROFILES_FILE" not in os.environ
