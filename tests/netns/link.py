"""An emulated network link between two network namespaces: two TAP devices and this
forwarder between them, which drops, delays or cuts frames. Standard library only: this
machine's kernel has no netem, and iptables is not installed on a fresh machine.

Run as a process (it must outlive nothing: the TAP devices vanish with it):

    python -m tests.netns.link TAP_A TAP_B

It creates both TAP devices, prints `ready`, then forwards frames both ways. Commands on
stdin, one per line: `loss P` (each direction drops a frame with probability P), `delay S`
(each direction holds every frame S seconds; ARP is delayed, never lost), `down` / `up`
(a partition), `stats` (prints the frame counts as JSON), `quit`.
"""

from __future__ import annotations

import contextlib
import fcntl
import heapq
import json
import os
import random
import select
import struct
import sys
import time

TUNSETIFF = 0x400454CA
IFF_TAP = 0x0002
IFF_NO_PI = 0x1000


def open_tap(name: str) -> int:
    fd = os.open("/dev/net/tun", os.O_RDWR | os.O_NONBLOCK)
    fcntl.ioctl(fd, TUNSETIFF, struct.pack("16sH", name.encode(), IFF_TAP | IFF_NO_PI))
    return fd


def main(argv: list[str]) -> int:
    a, b = open_tap(argv[0]), open_tap(argv[1])
    other = {a: b, b: a}
    loss, delay, up = 0.0, 0.0, True
    rng = random.Random(int(argv[2]) if len(argv) > 2 else None)
    queue: list[tuple[float, int, int, bytes]] = []  # (release time, seq, fd, frame)
    seq = 0
    counts = {"forwarded": 0, "dropped": 0}
    print("ready", flush=True)
    stdin = sys.stdin.fileno()
    while True:
        now = time.monotonic()
        while queue and queue[0][0] <= now:
            _, _, fd, frame = heapq.heappop(queue)
            with contextlib.suppress(OSError):  # the device is not up yet, or gone
                os.write(fd, frame)
        wait = max(0.0, queue[0][0] - now) if queue else 1.0
        ready, _, _ = select.select([a, b, stdin], [], [], wait)
        for fd in ready:
            if fd == stdin:
                line = sys.stdin.readline()
                if not line or line.strip() == "quit":
                    return 0
                words = line.split()
                if words[0] == "loss":
                    loss = float(words[1])
                elif words[0] == "delay":
                    delay = float(words[1])
                elif words[0] in ("down", "up"):
                    up = words[0] == "up"
                elif words[0] == "stats":
                    print(json.dumps(counts), flush=True)
                continue
            while True:
                try:
                    frame = os.read(fd, 65536)
                except BlockingIOError:
                    break
                except OSError:  # the namespace and its device are gone: the test is over
                    return 0
                # ARP is spared: a lost ARP reply makes the kernel drop every packet to that
                # neighbour for seconds, an artifact a link with MAC retries (Wi-Fi) does not have.
                arp = frame[12:14] == b"\x08\x06"
                if not up or (not arp and rng.random() < loss):
                    counts["dropped"] += 1
                    continue
                counts["forwarded"] += 1
                seq += 1
                heapq.heappush(queue, (time.monotonic() + delay, seq, other[fd], frame))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
