"""The dashboard's ASGI app (Starlette, served by uvicorn): the page, its static files and one
WebSocket per page.

One poller per app reads the history's new rows every ``poll_s`` seconds (in a worker thread:
the event loop only forwards), turns them into records (:class:`~dashboard.view.RunView`) and
hands each batch to every connected page. A page that connects is sent the run's static
description (``hello``), then every record so far, then each new batch (``data``), and when
the run has ended its stop message (``finished``). What the page sends is checked
(:mod:`dashboard.commands`) and, while the run is live, sent to the run's clock on
``ops/inject`` exactly as ``wncs inject`` sends it; the answer is ``ack`` or ``error`` with the
reason. Nothing the page sends can stop the server or the run.

The dashboard is not a clock participant: the run never waits for it. A page that falls
behind only makes its own queue longer.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import anyio
import uvicorn
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from core.errors import ConfigError
from dashboard.commands import CommandError, parse
from dashboard.feed import HistoryFeed
from dashboard.view import RunView
from runtime.artefacts import HISTORY_FILE, RUN_FILE, SCENARIO_FILE
from runtime.inject import send
from runtime.security import DASHBOARD, login_of
from scenario import load_scenario

__all__ = ["Dashboard", "create_app", "serve", "STATIC"]

log = logging.getLogger("wncs.dashboard")

STATIC = Path(__file__).with_name("static")


@dataclass
class RunInfo:
    run_id: str | None
    endpoint: str | None
    engine: str | None


def _run_info(run_dir: Path) -> RunInfo:
    path = run_dir / RUN_FILE
    try:
        info = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ConfigError(f"{path}: not a run directory ({err})") from err
    if not isinstance(info, dict):
        raise ConfigError(f"{path}: not a run directory (not a JSON object)")
    return RunInfo(info.get("run_id"), info.get("endpoint"), info.get("engine"))


class Dashboard:
    """The state one app serves: the run, its history feed and view, the connected pages."""

    def __init__(self, run_dir: str | Path, *, poll_s: float = 0.1, max_points: int = 2000) -> None:
        self.run_dir = Path(run_dir)
        self.info = _run_info(self.run_dir)
        if self.info.engine == "direct":
            raise ConfigError(
                f"{self.run_dir}: a direct-engine run has no history to show; run the scenario "
                "with --engine threads or processes"
            )
        self.scenario = load_scenario(self.run_dir / SCENARIO_FILE)
        self.feed = HistoryFeed(self.run_dir / HISTORY_FILE)
        self.view = RunView(self.scenario, max_points=max_points)
        self.poll_s = poll_s
        self.finished: dict[str, Any] | None = None
        self.pages: set[asyncio.Queue[str]] = set()
        self._lock = threading.Lock()
        self._wall0: float | None = None
        self.step()  # what the history holds already (all of it, for a finished run)

    @property
    def live(self) -> bool:
        return self.finished is None and self.info.endpoint is not None

    # -- reading the history ----------------------------------------------------------------------
    def step(self) -> list[str]:
        """Read what the history has new; the messages for the pages (JSON texts). Runs in a
        worker thread."""
        out: list[str] = []
        with self._lock:
            if self.finished is not None:
                return out
            stop = self.feed.stop()  # read before the rows: no row can come after the stop
            while True:
                rows = self.feed.read()
                if not rows:
                    break
                batch = self.view.ingest(rows)
                if stop is None:
                    now = time.monotonic()
                    if self._wall0 is None:
                        self._wall0 = now
                    batch.setdefault("clock", []).append([now - self._wall0, self.view.t])
                    self.view.streams.setdefault("clock", []).append(batch["clock"][-1])
                out.append(self._data(batch))
            if stop is not None:
                self.finished = stop
                out.append(json.dumps({"type": "finished", "stop": stop}))
        return out

    def _data(self, batch: dict[str, list[Any]]) -> str:
        return json.dumps(
            {
                "type": "data",
                "t": self.view.t,
                "round": self.view.round,
                "rows": self.view.rows,
                "append": batch,
            },
            separators=(",", ":"),
        )

    def hello(self) -> str:
        return json.dumps(
            {
                "type": "hello",
                "run_id": self.info.run_id,
                "run_dir": str(self.run_dir),
                "live": self.live,
                "static": self.view.static(),
            }
        )

    def attach(self) -> tuple[asyncio.Queue[str], list[str]]:
        """A new page: its queue, and what it is sent first (every record so far)."""
        queue: asyncio.Queue[str] = asyncio.Queue()
        with self._lock:
            first = [self._data(self.view.snapshot())]
            if self.finished is not None:
                first.append(json.dumps({"type": "finished", "stop": self.finished}))
            self.pages.add(queue)
        return queue, first

    async def poll(self) -> None:
        """Forever: read the history and hand the new batches to every page."""
        while True:
            for text in await anyio.to_thread.run_sync(self.step):
                for queue in list(self.pages):
                    queue.put_nowait(text)
            await asyncio.sleep(self.poll_s)

    # -- requests from a page ---------------------------------------------------------------------
    async def request(self, text: str) -> dict[str, Any]:
        """Check and send one request; the answer for the page."""
        try:
            command = parse(text, self.run_dir)
        except CommandError as err:
            return {"type": "error", "id": err.id, "reason": err.reason}
        if not self.live:
            return {
                "type": "error",
                "id": command.id,
                "reason": "the run has ended: a replay takes no requests",
            }
        assert self.info.endpoint is not None and self.info.run_id is not None
        creds = login_of(self.run_dir, DASHBOARD)  # a secure run: the dashboard's own login
        try:
            await anyio.to_thread.run_sync(
                lambda: send(
                    self.info.endpoint,
                    self.info.run_id,
                    command.request,
                    timeout=5.0,
                    settings=creds,
                )
            )
        except ConfigError as err:
            return {"type": "error", "id": command.id, "reason": str(err)}
        log.info("request sent: %s", command.summary)
        return {
            "type": "ack",
            "id": command.id,
            "summary": command.summary,
            "request": command.request.model_dump(mode="json", exclude_none=True),
        }


def create_app(dashboard: Dashboard) -> Starlette:
    """The ASGI app serving ``dashboard``."""

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        task = asyncio.create_task(dashboard.poll())
        try:
            yield
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def index(request: Request) -> FileResponse:
        return FileResponse(STATIC / "index.html")

    async def status(request: Request) -> JSONResponse:
        return JSONResponse(
            {
                "live": dashboard.live,
                "t": dashboard.view.t,
                "rows": dashboard.view.rows,
                "finished": dashboard.finished is not None,
            }
        )

    async def socket(ws: WebSocket) -> None:
        await ws.accept()
        queue, first = dashboard.attach()
        try:
            await ws.send_text(dashboard.hello())
            for text in first:
                await ws.send_text(text)
            async with anyio.create_task_group() as tg:
                tg.start_soon(_forward, ws, queue)
                await _answer(ws, dashboard)
                tg.cancel_scope.cancel()
        except WebSocketDisconnect:
            pass
        finally:
            dashboard.pages.discard(queue)

    return Starlette(
        routes=[
            Route("/", index),
            Route("/status", status),
            Route("/favicon.ico", lambda request: Response(status_code=204)),
            WebSocketRoute("/ws", socket),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        lifespan=lifespan,
    )


async def _forward(ws: WebSocket, queue: asyncio.Queue[str]) -> None:
    """Hand the page its batches until it goes away (a page that left ends only this task)."""
    while True:
        text = await queue.get()
        try:
            await ws.send_text(text)
        except (WebSocketDisconnect, RuntimeError, OSError):
            return


async def _answer(ws: WebSocket, dashboard: Dashboard) -> None:
    """Answer the page's requests until it goes away."""
    while True:
        message = await ws.receive()
        if message["type"] == "websocket.disconnect":
            return
        text = message.get("text")
        if text is None:
            answer: dict[str, Any] = {"type": "error", "id": None, "reason": "binary message"}
        else:
            answer = await dashboard.request(text)
        await ws.send_text(json.dumps(answer))


def serve(
    dashboard: Dashboard,
    *,
    host: str = "127.0.0.1",
    port: int = 8765,
    on_ready: Callable[[str], None] | None = None,
) -> None:
    """Serve ``dashboard`` until interrupted; ``on_ready(url)`` once it listens."""
    config = uvicorn.Config(create_app(dashboard), host=host, port=port, log_level="warning")
    server = uvicorn.Server(config)

    async def main() -> None:
        task = asyncio.create_task(server.serve())
        while not server.started and not task.done():
            await asyncio.sleep(0.02)
        if server.started and on_ready is not None:
            sock = server.servers[0].sockets[0].getsockname()
            on_ready(f"http://{sock[0]}:{sock[1]}/")
        with contextlib.suppress(SystemExit):  # uvicorn's way of saying it could not bind
            await task

    asyncio.run(main())
    if not server.started:
        raise ConfigError(
            f"--port {port}: the dashboard cannot listen on {host}:{port} (in use already?)"
        )
