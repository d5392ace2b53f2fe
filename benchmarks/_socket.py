"""Which WebSocket server the live page uses, by measurement (``bench_vision --socket``).

A client sends a camera frame's worth of bytes (a 640x360 JPEG is 30-50 KB) 30 times a
second and waits for each answer (a pose's worth of JSON, 2 KB), as the page and the loop
exchange them; the server answers from a thread of its own, as the performance loop
publishes. Per server: the round trip's p50 and p99 over ``seconds``, and the CPU time
the server process spent a second (the same process here; the client's share is the
same for all). ``websockets``' threaded server is what ``vision/_stage.py`` uses; its
asyncio server and aiohttp's (when installed: ``pip install aiohttp``; not a dependency)
are the alternatives the issue names.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from websockets.sync.client import connect

FRAME = os.urandom(40_000)
POSE = b"x" * 2_000


def _threaded() -> Iterator[int]:
    from websockets.sync.server import ServerConnection, serve

    def handler(conn: ServerConnection) -> None:
        for _ in conn:
            conn.send(POSE)

    with serve(handler, "127.0.0.1", 0, max_size=1 << 20, compression=None) as server:
        threading.Thread(target=server.serve_forever, daemon=True).start()
        yield int(server.socket.getsockname()[1])
        server.shutdown()


def _in_loop(start: Callable[[], Any]) -> Iterator[int]:
    """Run an asyncio server made by ``start()`` (which returns its port) in a thread."""
    loop = asyncio.new_event_loop()
    got: dict[str, Any] = {}
    ready = threading.Event()

    def main() -> None:
        asyncio.set_event_loop(loop)
        got["port"], got["stop"] = loop.run_until_complete(start())
        ready.set()
        loop.run_forever()

    thread = threading.Thread(target=main, daemon=True)
    thread.start()
    ready.wait(10)
    try:
        yield int(got["port"])
    finally:
        asyncio.run_coroutine_threadsafe(got["stop"](), loop).result(10)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)


def _asyncio() -> Iterator[int]:
    from websockets.asyncio.server import serve

    async def handler(conn: Any) -> None:
        async for _ in conn:
            await conn.send(POSE)

    async def start() -> tuple[int, Any]:
        server = await serve(handler, "127.0.0.1", 0, max_size=1 << 20, compression=None)

        async def stop() -> None:
            server.close()
            await server.wait_closed()

        return server.sockets[0].getsockname()[1], stop

    yield from _in_loop(start)


def _aiohttp() -> Iterator[int]:
    from aiohttp import WSMsgType, web

    async def ws(request: Any) -> Any:
        conn = web.WebSocketResponse(max_msg_size=1 << 20)
        await conn.prepare(request)
        async for msg in conn:
            if msg.type == WSMsgType.BINARY:
                await conn.send_bytes(POSE)
        return conn

    async def start() -> tuple[int, Any]:
        app = web.Application()
        app.router.add_get("/", ws)
        runner = web.AppRunner(app)
        await runner.setup()
        site = web.TCPSite(runner, "127.0.0.1", 0)
        await site.start()
        port = runner.addresses[0][1]
        return port, runner.cleanup

    yield from _in_loop(start)


SERVERS = {"websockets threaded": _threaded, "websockets asyncio": _asyncio, "aiohttp": _aiohttp}


def one(server: Callable[[], Iterator[int]], seconds: float) -> dict[str, Any]:
    with (
        contextlib.contextmanager(server)() as port,
        connect(f"ws://127.0.0.1:{port}/", max_size=1 << 20, compression=None) as ws,
    ):
        trips = []
        cpu0, t0 = time.process_time(), time.perf_counter()
        n = 0
        while time.perf_counter() - t0 < seconds:
            a = time.perf_counter()
            ws.send(FRAME)
            ws.recv(timeout=5)
            trips.append((time.perf_counter() - a) * 1000)
            n += 1
            delay = t0 + n / 30.0 - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        cpu = (time.process_time() - cpu0) / (time.perf_counter() - t0)
    ms = np.array(trips)
    return {
        "round_trip_ms_p50": round(float(np.percentile(ms, 50)), 3),
        "round_trip_ms_p99": round(float(np.percentile(ms, 99)), 3),
        "cpu_share_of_a_core": round(cpu, 4),
        "messages": n,
    }


def sockets(seconds: float = 10.0) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, server in SERVERS.items():
        try:
            out[name] = one(server, seconds)
        except ImportError as exc:
            out[name] = f"not installed ({exc.name})"
    return out
