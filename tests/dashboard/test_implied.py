"""The dashboard says which active layers are implied, and by what (issue 28, item 1)."""

from __future__ import annotations

from contextros.dashboard.model import DashboardModel


def test_the_active_layers_and_each_switch_name_what_implies_them() -> None:
    m = DashboardModel(["/r1"], clock=lambda: 1000.0)
    m.registry(
        "/r1",
        {
            "layers": [
                {"name": "Mission", "implies": ["Flight"]},
                {"name": "Flight", "implies": ["CameraHigh", "Propulsion"]},
                {"name": "Propulsion", "implies": []},
                {"name": "CameraHigh"},  # an older manager's answer: no `implies`
            ]
        },
    )
    active = ["CameraHigh", "Propulsion", "Flight", "Mission"]
    m.state("/r1", 3, active, "cli", "go", stamp=999.0, manager_id="m")
    m.state("/r1", 4, ["Propulsion"], "cli", "", stamp=999.5, manager_id="m")
    robot = m.snapshot()["robots"][0]
    assert robot["implied_by"] == {}
    assert robot["history"][1]["implied_by"] == {
        "CameraHigh": ["Flight"],
        "Flight": ["Mission"],
        "Propulsion": ["Flight"],
    }
