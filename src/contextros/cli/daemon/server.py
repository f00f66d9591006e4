"""The daemon: client nodes kept warm, serving the command line over a private socket.

Each worker thread has its own client node (and executor) per namespace, created on first
use and kept: a node that has discovered the manager, and that the manager has discovered,
answers a command in milliseconds. Only one daemon runs per place: it holds the place's
lock for its whole life, so a second one started by a racing command exits at once.
"""

from __future__ import annotations

import contextlib
import faulthandler
import fcntl
import itertools
import os
import signal
import socket
import struct
import sys
import threading
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from typing import IO, TYPE_CHECKING, Any

from contextros.cli.client_answers import client_answer
from contextros.cli.daemon.place import DaemonPlace
from contextros.cli.daemon.wire import MAX_REQUEST, WireError, receive, request_problem, send
from contextros.errors import LayerError

if TYPE_CHECKING:
    from contextros.ros import LayerClient

WORKERS = 4  # commands served at once; more wait in line, up to:
MAX_CONNECTIONS = 16  # beyond that a command is told `busy` and asks the manager itself
MAX_NAMESPACES = 8  # client nodes per worker
READ_TIMEOUT = 5.0  # a connection that sends no whole request in time is dropped
DEFAULT_IDLE_TIMEOUT = 900.0
WARM_UP_WAIT = 5.0
# Seconds the way out may take (commands in flight end, nodes and rclpy are torn down):
# Fast DDS can deadlock deleting a participant while holding the GIL, so a C thread
# (faulthandler's) ends the process then, writing the stack it hung in to the log.
TEARDOWN_LIMIT = 10.0


def log(text: str) -> None:
    print(f"{time.strftime('%Y-%m-%d %H:%M:%S')} daemon {os.getpid()}: {text}", flush=True)


class _TooManyNamespaces(Exception):
    pass


class DaemonServer:
    def __init__(
        self,
        place: DaemonPlace,
        idle_timeout: float = DEFAULT_IDLE_TIMEOUT,
        warm_namespace: str | None = None,
        expected_key: str | None = None,
    ) -> None:
        self.place = place
        self.expected_key = expected_key
        self.idle_timeout = idle_timeout
        self.warm_namespace = warm_namespace
        self._stop = threading.Event()
        self._local = threading.local()
        self._lock = threading.Lock()
        self._nodes: list[Any] = []
        self._names = itertools.count(1)
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)
        self._busy = 0
        self._last_activity = time.monotonic()
        self._socket_inode = -1

    def run(self) -> int:
        """Serve until stopped, idle for `idle_timeout` (0: never) or signalled."""
        with ExitStack() as stack:
            lock = stack.enter_context(open(self.place.lock, "a"))
            if not _take_lock(lock):
                log(f"another daemon serves {self.place.socket}")
                return 0
            if self.expected_key is not None:  # started by a command
                if self.place.key != self.expected_key:
                    log(
                        f"not serving: this daemon's code or environment differs from the "
                        f"command's (key {self.place.key}, the command's {self.expected_key})"
                    )
                    return 1
                _restart_log()
            from contextros.installation import ros_problem

            if problem := ros_problem():
                log(f"not serving: {problem}")
                return 1
            from contextros.cli.ros_commands import use_packaged_profile

            use_packaged_profile("client_discovery.xml")
            import rclpy

            rclpy.init(args=["contextros_daemon"])
            stack.callback(rclpy.try_shutdown)
            stack.callback(self._destroy_nodes)
            for signum in (signal.SIGTERM, signal.SIGINT):
                signal.signal(signum, lambda *_: self._stop.set())
            listener = stack.enter_context(self._listen())
            workers = stack.enter_context(ThreadPoolExecutor(WORKERS, "contextros-daemon"))
            # On the way out ROS shuts down before the workers are joined: a command still
            # waiting (for the manager, for acknowledgements) ends now, not at its deadline.
            stack.callback(rclpy.try_shutdown)
            stack.callback(faulthandler.dump_traceback_later, TEARDOWN_LIMIT, exit=True)
            workers.submit(self._warm_up)
            domain = os.environ.get("ROS_DOMAIN_ID", "0")
            log(f"serving {self.place.socket} (ROS_DOMAIN_ID={domain})")
            self._serve(listener, workers)
            log("stopping")
        return 0

    def _listen(self) -> socket.socket:
        path = self.place.socket
        path.unlink(missing_ok=True)  # a dead daemon's: this one holds the lock
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        listener.bind(str(path))
        os.chmod(path, 0o600)
        listener.listen(MAX_CONNECTIONS)
        listener.settimeout(0.5)
        self._socket_inode = path.stat().st_ino
        return listener

    def _serve(self, listener: socket.socket, workers: ThreadPoolExecutor) -> None:
        try:
            while not self._stop.is_set():
                if self._idle():
                    log(f"idle for {self.idle_timeout:g} s")
                    return
                if not self._socket_is_ours():
                    log(f"{self.place.socket} was removed or replaced")
                    return
                try:
                    connection, _ = listener.accept()
                except TimeoutError:
                    continue
                if not _same_user(connection):
                    connection.close()
                    continue
                if not self._slots.acquire(blocking=False):
                    self._answer_busy(connection)
                    continue
                workers.submit(self._handle, connection)
        finally:
            # No new command from here on; the ones in flight end (see run).
            if self._socket_is_ours():
                self.place.socket.unlink(missing_ok=True)

    def _socket_is_ours(self) -> bool:
        """Whether the place's socket is still the one this daemon listens on (a removed
        directory, or another daemon's socket, ends this one)."""
        try:
            return self.place.socket.stat().st_ino == self._socket_inode
        except OSError:
            return False

    def _idle(self) -> bool:
        with self._lock:
            quiet_for = time.monotonic() - self._last_activity
            return self.idle_timeout > 0 and self._busy == 0 and quiet_for > self.idle_timeout

    @staticmethod
    def _answer_busy(connection: socket.socket) -> None:
        with connection:
            try:
                connection.settimeout(READ_TIMEOUT)
                send(connection, {"outcome": "busy", "message": "the daemon is busy"})
            except OSError:
                pass

    def _handle(self, connection: socket.socket) -> None:
        counted = False
        try:
            with connection:
                request = receive(connection, MAX_REQUEST, within=READ_TIMEOUT)
                # Looking at the daemon (ping) neither keeps it alive nor holds its exit.
                if request.get("command") != "ping":
                    counted = True
                    with self._lock:
                        self._busy += 1
                connection.settimeout(None)
                answer = self._answer(request)
                connection.settimeout(READ_TIMEOUT)
                send(connection, answer)
        except (OSError, WireError) as error:
            log(f"a connection failed: {error}")
        except Exception:  # a bug, or ROS shut down under a command by a stop: logged
            log(f"a command failed:\n{traceback.format_exc()}")
        finally:
            if counted:
                with self._lock:
                    self._busy -= 1
                    self._last_activity = time.monotonic()
            self._slots.release()

    def _answer(self, request: dict[str, Any]) -> dict[str, Any]:
        if problem := request_problem(request):
            return {"outcome": "refused", "message": f"invalid request: {problem}"}
        command = request["command"]
        if command == "ping":
            return {"outcome": "pong", "pid": os.getpid(), "key": self.place.key}
        if command == "stop":
            self._stop.set()
            return {"outcome": "stopping", "pid": os.getpid()}
        try:
            client = self._client(request["namespace"])
        except _TooManyNamespaces:
            return {"outcome": "busy", "message": "too many namespaces in one daemon"}
        return client_answer(client, request)

    def _client(self, namespace: str | None) -> LayerClient:
        """This worker's client in `namespace`, created on first use."""
        from rclpy.executors import SingleThreadedExecutor

        from contextros.ros import LayerClient
        from contextros.ros.client import quiet_node

        namespace = None if namespace in ("", "/") else namespace  # one node for the root
        clients: dict[str | None, LayerClient] = self._local.__dict__.setdefault("clients", {})
        if namespace not in clients:
            if len(clients) >= MAX_NAMESPACES:
                raise _TooManyNamespaces
            node = quiet_node(f"contextros_daemon_{os.getpid()}_{next(self._names)}", namespace)
            with self._lock:
                self._nodes.append(node)
            clients[namespace] = LayerClient(node, executor=SingleThreadedExecutor())
        return clients[namespace]

    def _warm_up(self) -> None:
        """Discover the manager before the first command needs it."""
        try:
            self._client(self.warm_namespace).wait_for_manager(WARM_UP_WAIT)
        except LayerError:
            pass  # no manager yet: the first command waits for it as usual
        except Exception:
            if not self._stop.is_set():  # (a stop shuts ROS down under it)
                log(f"warming up failed:\n{traceback.format_exc()}")

    def _destroy_nodes(self) -> None:
        with self._lock:
            for node in self._nodes:
                with contextlib.suppress(Exception):  # ROS may be shut down already
                    node.destroy_node()
            self._nodes.clear()


def _take_lock(lock: IO[str]) -> bool:
    """The place's lock, waiting up to a second: a command may be probing it
    (`client.starting`) at the very moment this daemon starts."""
    deadline = time.monotonic() + 1.0
    while True:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.02)


def _restart_log() -> None:
    """Empty the log the command opened for this daemon (appending: racing commands do not
    truncate a running daemon's log), now that this daemon is the one serving."""
    if sys.stdout.isatty():
        return
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
        os.ftruncate(sys.stdout.fileno(), 0)


def _same_user(connection: socket.socket) -> bool:
    """Whether the peer runs as this daemon's user (the directory's mode already keeps
    others out; this holds even if the socket were reached another way)."""
    if not hasattr(socket, "SO_PEERCRED"):
        return True
    size = struct.calcsize("3i")
    credentials = connection.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, size)
    uid: int = struct.unpack("3i", credentials)[1]
    return uid == os.getuid()


def serve(
    place: DaemonPlace,
    idle_timeout: float,
    warm_namespace: str | None,
    expected_key: str | None = None,
) -> int:
    try:
        return DaemonServer(place, idle_timeout, warm_namespace, expected_key).run()
    except Exception:
        log(f"failed:\n{traceback.format_exc()}")
        sys.stdout.flush()
        return 1
