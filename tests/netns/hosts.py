"""Two "hosts" on one machine: network namespaces joined by an emulated link (tests.netns.link).

    with TwoHosts() as hosts:
        manager_side = hosts.group("a")      # a ProcessGroup whose children run in host a
        nodes_side = hosts.group("b")
        hosts.impair(loss=0.3, delay=0.05)   # each direction
        hosts.cut() / hosts.heal()

Names and the subnet include this process's id and a counter, so parallel test workers
and test runs never meet; everything (processes, namespaces, the forwarder and with it the
TAP devices) is removed on exit, also on an exception or Ctrl-C, and namespaces left over
by a test run that was killed are removed at the next start. Needs root (developers'
machines and CI run as root).
"""

from __future__ import annotations

import atexit
import contextlib
import itertools
import os
import re
import subprocess
import sys
from pathlib import Path
from types import TracebackType

from tests.ros.processes import ProcessGroup

PREFIX = "crosn"  # namespaces: crosn<pid>x<n>a / b
_counter = itertools.count()
REPO = Path(__file__).resolve().parents[2]


def available() -> str:
    """Why two-host tests cannot run here ("" if they can)."""
    if os.geteuid() != 0:
        return "network namespaces need root"
    if not Path("/dev/net/tun").exists():
        return "no /dev/net/tun"
    try:
        subprocess.run(["ip", "netns", "list"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError) as error:
        return f"`ip netns` does not work: {error}"
    return ""


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


def remove_leftovers() -> None:
    """Namespaces of test runs whose process is gone (killed before its clean-up)."""
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    for name in re.findall(rf"^({PREFIX}(\d+)x\d+[ab])\b", listed, re.M):
        pid = int(name[1])
        if not Path(f"/proc/{pid}").exists():
            with contextlib.suppress(subprocess.CalledProcessError):
                _ip("netns", "del", name[0])


class TwoHosts:
    def __init__(self, domain_id: int | None = None, seed: int | None = None) -> None:
        run = f"{os.getpid()}x{next(_counter)}"
        self.names = {side: f"{PREFIX}{run}{side}" for side in "ab"}
        # Interface names have at most 15 characters.
        short = f"{os.getpid() % 100000}{run.split('x')[1]}"
        self.taps = {side: f"crt{short}{side}"[:15] for side in "ab"}
        octet = (os.getpid() * 7 + int(run.split("x")[1])) % 250 + 1
        self.addresses = {"a": f"10.203.{octet}.1", "b": f"10.203.{octet}.2"}
        self.domain_id = domain_id if domain_id is not None else int(os.environ["ROS_DOMAIN_ID"])
        self.seed = seed
        self.groups: list[ProcessGroup] = []
        self._link: subprocess.Popen[str] | None = None

    def __enter__(self) -> TwoHosts:
        remove_leftovers()
        atexit.register(self.close)
        try:
            self._start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.close()

    def _start(self) -> None:
        argv = [sys.executable, "-m", "tests.netns.link", self.taps["a"], self.taps["b"]]
        if self.seed is not None:
            argv.append(str(self.seed))
        self._link = subprocess.Popen(
            argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=REPO
        )
        assert self._link.stdout is not None
        if self._link.stdout.readline().strip() != "ready":
            raise RuntimeError("the link emulator did not start")
        for side in "ab":
            ns, tap = self.names[side], self.taps[side]
            _ip("netns", "add", ns)
            _ip("link", "set", tap, "netns", ns)
            _ip("-n", ns, "addr", "add", f"{self.addresses[side]}/24", "dev", tap)
            _ip("-n", ns, "link", "set", "lo", "up")
            _ip("-n", ns, "link", "set", tap, "up")
            # Multicast discovery leaves through the link (there is no other interface).
            _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", tap)

    def group(self, side: str) -> ProcessGroup:
        """Processes started from this group run in host `side` ("a" or "b")."""
        other = self.addresses["b" if side == "a" else "a"]
        group = ProcessGroup(
            prefix=("ip", "netns", "exec", self.names[side]),
            env={
                "ROS_DOMAIN_ID": str(self.domain_id),
                "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                "ROS_STATIC_PEERS": other,
                # UDP only: shared memory between the namespaces would bypass the link.
                "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
                "PYTHONPATH": str(REPO),
            },
        )
        self.groups.append(group)
        return group

    def _command(self, line: str) -> None:
        assert self._link is not None and self._link.stdin is not None
        self._link.stdin.write(line + "\n")
        self._link.stdin.flush()

    def impair(self, loss: float = 0.0, delay: float = 0.0) -> None:
        """Each direction loses a frame with probability `loss` and delays every frame."""
        self._command(f"loss {loss}")
        self._command(f"delay {delay}")

    def cut(self) -> None:
        self._command("down")

    def heal(self) -> None:
        self._command("up")

    def stats(self) -> dict[str, int]:
        import json

        self._command("stats")
        assert self._link is not None and self._link.stdout is not None
        return dict(json.loads(self._link.stdout.readline()))

    def close(self) -> None:
        for group in self.groups:
            group.kill_all()
        self.groups.clear()
        for ns in self.names.values():
            with contextlib.suppress(subprocess.CalledProcessError):
                _ip("netns", "del", ns)
        if self._link is not None and self._link.poll() is None:
            with contextlib.suppress(OSError):
                self._command("quit")
            try:
                self._link.wait(5)
            except subprocess.TimeoutExpired:
                self._link.kill()
                self._link.wait(5)
        atexit.unregister(self.close)
