"""A context node in its own process, for the ROS tests.

It implements a few layers with relations and a layered method, and prints one JSON line
per event on stdout (`ready`, `applied` with the epoch and what the layered method now
returns, `critical-open`/`critical-closed`). Commands on stdin: `critical SECONDS` opens a
critical section in another thread for that long.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time

import rclpy
from rclpy.utilities import remove_ros_args

from contextros.core import Layer, critical, layered, proceed
from contextros.protocol import LayerState
from contextros.ros import ContextNode, spin_nodes

LAYERS = {
    "Indoor": Layer("Indoor", group="location"),
    "Outdoor": Layer("Outdoor", group="location"),
    "Night": Layer("Night"),
    "Slow": Layer("Slow", excludes=("Fast",)),
    "Fast": Layer("Fast"),
    "Gps": Layer("Gps", requires=("Outdoor",)),
    # The rescue robot's disasters (issue 11): Rubble's partials must wrap Flooded's.
    "Rubble": Layer("Rubble", after=("Flooded",)),
    "Flight": Layer("Flight"),
    "Flooded": Layer("Flooded"),
    # A hierarchy three levels deep (issue 28): a mission implies flying, which implies the
    # propulsion and the high-resolution camera.
    "Mission": Layer("Mission", implies=("Airborne",)),
    "Airborne": Layer("Airborne", implies=("Propulsion", "CameraHigh")),
    "Propulsion": Layer("Propulsion"),
    "CameraHigh": Layer("CameraHigh", group="camera"),
    "CameraLow": Layer("CameraLow", group="camera"),
    "Survey": Layer("Survey", implies=("CameraHigh",)),
}
DEFAULT_LAYERS = ("Indoor", "Outdoor", "Night", "Slow", "Fast", "Gps")


class Cleaner:
    @layered
    def mode(self) -> str:
        return "base"

    @mode.partial(LAYERS["Indoor"])
    def mode(self) -> str:
        return "wipe+" + proceed(self)

    @mode.partial(LAYERS["Outdoor"])
    def mode(self) -> str:
        return "vacuum+" + proceed(self)

    @mode.partial(LAYERS["Night"])
    def mode(self) -> str:
        return "quiet+" + proceed(self)


def emit(event: str, **fields: object) -> None:
    print(json.dumps({"event": event, "t": time.monotonic(), **fields}), flush=True)


def hold_critical(seconds: float) -> None:
    with critical():
        emit("critical-open")
        time.sleep(seconds)
        emit("critical-closed")


def read_commands() -> None:
    for line in sys.stdin:
        words = line.split()
        if words and words[0] == "critical":
            threading.Thread(target=hold_critical, args=(float(words[1]),), daemon=True).start()


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", required=True)
    parser.add_argument("--layers", default=",".join(DEFAULT_LAYERS))
    parser.add_argument("--heartbeat", type=float, default=0.25)
    parser.add_argument("--manager-timeout", type=float, default=3.0)
    parser.add_argument("--stubborn", help="a layer whose on_deactivate hook always raises")
    parser.add_argument("--also", help="a second context node in this process (it is hosted)")
    parser.add_argument(
        "--veto", help="an application veto: refuse every proposal with this ('raise': it raises)"
    )
    parser.add_argument("--veto-sleep", type=float, default=0.0, help="each veto call takes this")
    args = parser.parse_args(remove_ros_args(sys.argv)[1:])
    if args.stubborn:
        old = LAYERS[args.stubborn]

        def refuse() -> None:
            raise RuntimeError(f"{args.stubborn} cannot be left now")

        # A later definition of a name replaces the earlier one (relations and hooks).
        LAYERS[args.stubborn] = Layer(
            old.name,
            group=old.group,
            excludes=old.excludes,
            requires=old.requires,
            on_deactivate=refuse,
        )
    rclpy.init(args=sys.argv)
    cleaner = Cleaner()
    node = ContextNode(
        args.name,
        layers=args.layers.split(","),
        heartbeat_period=args.heartbeat,
        manager_timeout=args.manager_timeout,
    )

    def on_applied(state: LayerState) -> None:
        emit("applied", epoch=state.epoch, active=list(state.active), mode=cleaner.mode())

    node.context_participant.add_listener(on_applied)
    node.context_participant.add_manager_listener(
        lambda lost: emit("manager-lost" if lost else "manager-found")
    )
    if args.veto or args.veto_sleep:

        def veto(proposal: LayerState) -> str | None:
            emit("veto-called", epoch=proposal.epoch, active=list(proposal.active))
            if args.veto == "raise":  # a veto that fails
                raise RuntimeError("veto exploded")
            time.sleep(args.veto_sleep)
            emit("veto-answered", epoch=proposal.epoch)
            return args.veto

        node.context_participant.add_veto(veto)
    threading.Thread(target=read_commands, daemon=True).start()
    emit("ready", node=node.get_fully_qualified_name(), mode=cleaner.mode())
    nodes = [node]
    if args.also:
        nodes.append(ContextNode(args.also, layers=["Night"]))
    spin_nodes(nodes)
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
