"""The dashboard's web server (aiohttp): the page, and a WebSocket that pushes the model.

Each client gets the whole snapshot on connection and after every change, never a backlog:
a client that reads slowly skips to the newest snapshot (one send in flight per client),
so a stalled tab costs no memory here.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import threading
from importlib import resources
from typing import Any

from aiohttp import WSMsgType, web

from contextros.dashboard.model import DashboardModel

STATIC = resources.files("contextros.dashboard") / "static"
PUSH_INTERVAL_MIN = 0.02  # seconds between two snapshots to one client, at most 50 per second


class DashboardServer:
    def __init__(self, model: DashboardModel) -> None:
        self.model = model
        self._wakeups: set[asyncio.Event] = set()  # one per connected page
        self._loop: asyncio.AbstractEventLoop | None = None
        self._loop_lock = threading.Lock()  # notify() against stop() closing the loop
        self.app = web.Application()
        self.app.router.add_get("/", self._index)
        self.app.router.add_get("/static/{name}", self._static)
        self.app.router.add_get("/ws", self._socket)
        self.app.router.add_get("/snapshot.json", self._snapshot)

    def notify(self) -> None:
        """The model changed (callable from any thread; nothing once the server stopped:
        the ROS thread may still report while the loop closes)."""
        with self._loop_lock:
            if self._loop is not None:
                self._loop.call_soon_threadsafe(self._wake_all)

    def _wake_all(self) -> None:
        for wakeup in self._wakeups:
            wakeup.set()

    async def start(self, host: str, port: int) -> tuple[web.AppRunner, int]:
        self._loop = asyncio.get_running_loop()
        runner = web.AppRunner(self.app, access_log=None)
        await runner.setup()
        site = web.TCPSite(runner, host, port)
        await site.start()
        bound = runner.addresses[0][1] if runner.addresses else port  # port 0: the one taken
        return runner, int(bound)

    async def stop(self, runner: web.AppRunner) -> None:
        """No more wake-ups from other threads, then the server's teardown."""
        with self._loop_lock:
            self._loop = None
        await runner.cleanup()

    async def _index(self, request: web.Request) -> web.StreamResponse:
        del request
        return web.Response(text=(STATIC / "index.html").read_text(), content_type="text/html")

    async def _static(self, request: web.Request) -> web.StreamResponse:
        name = request.match_info["name"]
        types = {".js": "text/javascript", ".css": "text/css", ".png": "image/png"}
        kind = next((t for suffix, t in types.items() if name.endswith(suffix)), None)
        if kind is None or "/" in name or name.startswith("."):
            raise web.HTTPNotFound()
        resource = STATIC / name
        if not resource.is_file():
            raise web.HTTPNotFound()
        return web.Response(body=resource.read_bytes(), content_type=kind)

    async def _snapshot(self, request: web.Request) -> web.StreamResponse:
        del request
        return web.json_response(self.model.snapshot())

    async def _socket(self, request: web.Request) -> web.StreamResponse:
        socket = web.WebSocketResponse(heartbeat=10.0)
        await socket.prepare(request)
        wakeup = asyncio.Event()
        self._wakeups.add(wakeup)
        sender = asyncio.create_task(self._push(socket, wakeup))
        try:
            async for message in socket:  # the page sends nothing; this waits for the close
                if message.type == WSMsgType.ERROR:
                    break
        finally:
            self._wakeups.discard(wakeup)
            sender.cancel()
        return socket

    async def _push(self, socket: web.WebSocketResponse, wakeup: asyncio.Event) -> None:
        """The newest snapshot whenever the model changed since the last one sent."""
        sent = -1
        with contextlib.suppress(ConnectionError, asyncio.CancelledError):
            while not socket.closed:
                wakeup.clear()
                if self.model.version != sent:
                    sent = self.model.version
                    await socket.send_str(json.dumps(self.model.snapshot()))
                    await asyncio.sleep(PUSH_INTERVAL_MIN)
                    continue
                await wakeup.wait()


def serve(server: DashboardServer, host: str, port: int, on_ready: Any) -> None:
    """Serve until SIGINT or SIGTERM; `on_ready(port)` once listening."""

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for signum in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(signum, stop.set)
        runner, bound = await server.start(host, port)
        on_ready(bound)
        try:
            await stop.wait()
        finally:
            await server.stop(runner)

    previous = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        asyncio.run(main())
    finally:  # the loop leaves the default handlers behind: the teardown keeps the caller's
        for signum, handler in previous.items():
            if handler is not None:
                signal.signal(signum, handler)
