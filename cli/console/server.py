"""The console's web app (Starlette, served by uvicorn) and ``serve``, which runs it.

Routes: ``/`` the page, ``/static/…`` its files, ``/ws`` the live link (state, frames, events
out; commands and frame acks in), ``/api/info``, ``/api/stats`` (frames drawn, latency),
``/api/runs``, ``/api/run``, ``/api/run/image`` (a frame, the reference, the object image, or the
condition: the object at a frame's pose) and ``/api/run/flow`` (the run browser), ``/api/progress``
(runs being written, from their progress sidecars), ``/api/protocol`` (a protocol's duration, frames
and disk with --set values, before it starts).

A WebSocket message must be a JSON object with a ``type``; anything else (not JSON, an array,
a number, binary, a field of the wrong type) is answered with a ``refused`` message naming
what was expected, and the link stays up: never a traceback (cli/console/messages.py).

Bound to 127.0.0.1 by default. On any other address every request needs the access token
printed at start (``?token=`` once, then a cookie); WebSockets from another origin are refused
either way, so a web page elsewhere cannot drive the rig through the browser.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import logging
import secrets
import signal
import socket
import sys
import time
from dataclasses import dataclass, field
from http.cookies import SimpleCookie
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from cli.console.flow import MarkerFlow
from cli.console.hub import Client, Hub
from cli.console.messages import MALFORMED, handle, parse
from cli.console.runs import ProgressWatch, RunLibrary, refusal, run_flow, run_image, run_series
from cli.console.worker import RigWorker
from common.errors import ToolError
from common.sensors import has_markers

log = logging.getLogger("rig.console")

STATIC = Path(__file__).parent / "static"
LOOPBACK = ("127.0.0.1", "localhost", "::1")
COOKIE = "rig_console_token"


@dataclass
class ConsoleOptions:
    """What the console serves: the rig (None: the run browser only) and which run files."""

    worker: RigWorker | None
    library: RunLibrary
    token: str | None = None  # required on every request when set
    open_run: str | None = None  # the run the page opens first (`dataset view RUN.h5`)
    sensor: str = "rgb"  # the live camera's sensor kind: marker kinds get marker-flow arrows
    hub: Hub = field(init=False)
    flow: MarkerFlow | None = field(init=False, default=None)
    progress: ProgressWatch = field(init=False)

    def __post_init__(self):
        self.hub = Hub(self.worker.now if self.worker else (lambda: float("nan")))
        self.progress = ProgressWatch(self.library)


class TokenGate:
    """ASGI middleware: with a token, every HTTP request and WebSocket must carry it (query
    ``token=`` or the cookie set from it); a good query token sets the cookie."""

    def __init__(self, app, token: str | None):
        self.app = app
        self.token = token

    def _given(self, scope) -> tuple[str, bool]:
        query = parse_qs(scope.get("query_string", b"").decode())
        if "token" in query:
            return query["token"][0], True
        cookies = SimpleCookie()
        for name, value in scope.get("headers", []):
            if name == b"cookie":
                cookies.load(value.decode("latin-1"))
        return (cookies[COOKIE].value if COOKIE in cookies else ""), False

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket") or self.token is None:
            return await self.app(scope, receive, send)
        given, from_query = self._given(scope)
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008})
                return
            response = Response("access token required: open the URL `rig console` printed\n", status_code=403)
            return await response(scope, receive, send)
        if not from_query or scope["type"] != "http":
            return await self.app(scope, receive, send)

        async def send_with_cookie(message):
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                headers.append((b"set-cookie", f"{COOKIE}={self.token}; HttpOnly; SameSite=Strict; Path=/".encode()))
                message = {**message, "headers": headers}
            await send(message)

        return await self.app(scope, receive, send_with_cookie)


def _same_origin(websocket: WebSocket) -> bool:
    origin = websocket.headers.get("origin")
    return origin is None or urlsplit(origin).netloc == websocket.headers.get("host")


def build_app(options: ConsoleOptions) -> Starlette:
    hub, worker, library = options.hub, options.worker, options.library

    @contextlib.asynccontextmanager
    async def lifespan(_app):
        if worker is not None:
            loop = asyncio.get_running_loop()
            worker.connect(
                on_state=lambda state: loop.call_soon_threadsafe(hub.on_state, state),
                on_frame=lambda frame: loop.call_soon_threadsafe(hub.on_frame, frame),
                on_event=lambda level, text: loop.call_soon_threadsafe(hub.on_event, level, text),
                on_rig=lambda status: loop.call_soon_threadsafe(hub.on_rig, status),
            )
            if has_markers(options.sensor):
                options.flow = MarkerFlow(lambda flow: loop.call_soon_threadsafe(hub.on_flow, flow))
                worker.frame_tap = options.flow.offer
                options.flow.start()
            worker.start()
        try:
            yield
        finally:
            if worker is not None:
                await asyncio.to_thread(worker.close)
            if options.flow is not None:
                await asyncio.to_thread(options.flow.close)

    async def index(_request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"cache-control": "no-store"})

    async def info(_request: Request) -> Response:
        rig = worker.rig if worker is not None else None
        return JSONResponse(
            {
                "live": worker is not None,
                "rig_error": worker.error if worker is not None else None,
                "rig": worker.rig_status if worker is not None else None,  # who holds the rig
                "axes": list(rig.axes) if rig is not None else [],
                "components": ["Fx", "Fy", "Fz", "Mx", "My", "Mz"],
                "open_run": options.open_run,
                "sensor": options.sensor,
                "marker_flow": options.flow is not None,
                "flow_scale": options.flow.scale if options.flow is not None else None,
                "protocols": await asyncio.to_thread(_protocols_for, worker) if worker is not None else [],
            }
        )

    async def stats(_request: Request) -> Response:
        return JSONResponse(hub.stats())

    async def runs(_request: Request) -> Response:
        listing = await asyncio.to_thread(library.listing)
        return JSONResponse(
            [{"name": name, "bytes": path.stat().st_size} for name, path in listing.items() if path.exists()]
        )

    async def run(request: Request) -> Response:
        try:
            path = library.path(request.query_params.get("name", ""))
            return JSONResponse(await asyncio.to_thread(run_series, path))
        except ToolError as exc:  # a damaged run file: 422, its one line shown on the page
            return _refused(exc)

    async def progress(_request: Request) -> Response:
        return JSONResponse(await asyncio.to_thread(options.progress.poll, time.time()))

    async def flow(request: Request) -> Response:
        try:
            path = library.path(request.query_params.get("name", ""))
            index = int(request.query_params.get("i", "0"))
            return JSONResponse(await asyncio.to_thread(run_flow, path, index))
        except (ToolError, ValueError) as exc:
            return _refused(exc)

    async def image(request: Request) -> Response:
        import cv2

        headers = {"cache-control": "no-store"}
        try:
            path = library.path(request.query_params.get("name", ""))
            index = int(request.query_params.get("i", "0"))
            kind = request.query_params.get("kind", "frame")
            if kind == "condition":  # the object at frame i's pose, as the model sees it
                from cli.console.condition_view import condition_at

                picture, pose = await asyncio.to_thread(condition_at, path, index)
                headers["x-pose"] = json.dumps(pose)
            else:
                picture = await asyncio.to_thread(run_image, path, kind, index)
        except (ToolError, ValueError) as exc:
            return _refused(exc)
        ok, buffer = cv2.imencode(".png", picture)
        return Response(buffer.tobytes(), media_type="image/png", headers=headers)

    async def protocol_plan(request: Request) -> Response:
        """A library protocol's duration, frames and disk with the page's --set values (checked as
        the command line checks them), before it is started."""
        from cli.console.protocol_run import check_settings, library_protocol, plan_summary

        simulated = worker is not None and worker.simulated
        try:
            settings = check_settings(request.query_params.getlist("set"))
            name = request.query_params.get("name", "")
            protocol = await asyncio.to_thread(library_protocol, name, options.sensor, simulated, settings)
            summary = await asyncio.to_thread(plan_summary, protocol, simulated)
        except ToolError as exc:
            return JSONResponse({"error": str(exc)}, status_code=400)
        return JSONResponse(summary)

    async def live(websocket: WebSocket) -> None:
        if not _same_origin(websocket):
            await websocket.close(code=1008)
            return
        await websocket.accept()
        peer = f"{websocket.client.host}:{websocket.client.port}" if websocket.client else "?"
        client = Client(websocket.send_text, websocket.send_bytes, peer)
        hub.join(client)
        if worker is not None:
            hub.tell(client, {"type": "history", "wrench": worker.history()})
        pump = asyncio.create_task(_pump(hub, client))
        try:
            while True:
                received = await websocket.receive()
                if received["type"] == "websocket.disconnect":
                    break
                message = parse(received.get("text"))
                if message is None:
                    hub.tell(client, {"type": "refused", "text": MALFORMED})
                    continue
                try:
                    handle(hub, worker, client, message, options.flow)
                except Exception as exc:  # a message nothing checked for: refused, and the link lives on
                    log.error(
                        "console: message %.200r from %s not handled: %s: %s", message, peer, type(exc).__name__, exc
                    )
                    hub.tell(client, {"type": "refused", "text": f"message not handled: {type(exc).__name__}: {exc}"})
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            hub.leave(client)
            if options.flow is not None:
                options.flow.wanted = hub.flow_wanted()
            pump.cancel()

    app = Starlette(
        routes=[
            Route("/", index),
            Route("/api/info", info),
            Route("/api/stats", stats),
            Route("/api/runs", runs),
            Route("/api/run", run),
            Route("/api/run/image", image),
            Route("/api/run/flow", flow),
            Route("/api/progress", progress),
            Route("/api/protocol", protocol_plan),
            WebSocketRoute("/ws", live),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        lifespan=lifespan,
    )
    app.add_middleware(TokenGate, token=options.token)
    return app


def _refused(exc: Exception) -> JSONResponse:
    """A run-browser read that failed, as the JSON error the page shows (cli/console/runs.py's ``refusal``)."""
    body, status = refusal(exc)
    return JSONResponse(body, status_code=status)


def _protocols_for(worker: RigWorker) -> list[str]:
    """The library protocols this console can start (for its sensor)."""
    from cli.console.protocol_run import library_protocol
    from protocols.spec import protocol_names

    names = []
    for name in protocol_names():
        try:
            library_protocol(name, worker.sensor, simulated=worker.simulated)
        except ToolError:
            continue
        names.append(name)
    return names


async def _pump(hub: Hub, client: Client) -> None:
    """Deliver to one browser until it goes away (the receiving side then ends too)."""
    try:
        await hub.pump(client)
    except (WebSocketDisconnect, RuntimeError, ConnectionError):
        pass  # the browser closed or the server is stopping: nothing left to deliver


class CannotListen(ToolError):
    """The console's address or port cannot be listened on."""


def bind(host: str, port: int) -> socket.socket:
    """A listening socket (port 0: any free one); CannotListen naming the address and --port/--host."""
    import errno

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except (socket.gaierror, UnicodeError) as exc:
        sock.close()
        raise CannotListen(f"cannot listen on {host}:{port}: {exc}; check --host") from None
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            hint = "another console or program listens there: pass --port N (--port 0 takes any free port)"
        elif exc.errno == errno.EACCES:
            hint = "ports below 1024 need root: pass --port N above 1023 (--port 0 takes any free port)"
        else:
            hint = "check --host (an address of this machine, e.g. 127.0.0.1 or 0.0.0.0)"
        raise CannotListen(f"cannot listen on {host}:{port}: {exc.strerror}; {hint}") from None
    sock.listen(64)
    sock.set_inheritable(True)
    return sock


def url_of(sock: socket.socket, host: str, token: str | None, path: str = "/") -> str:
    port = sock.getsockname()[1]
    shown = "127.0.0.1" if host in ("0.0.0.0", "") else (f"[{host}]" if ":" in host else host)
    return f"http://{shown}:{port}{path}" + (f"?token={token}" if token else "")


def make_token(host: str) -> str | None:
    """None on loopback; elsewhere a fresh 128-bit token."""
    return None if host in LOOPBACK else secrets.token_urlsafe(16)


def serve(options: ConsoleOptions, sock: socket.socket, *, log_level: str = "warning") -> None:
    """Run the console on ``sock`` until Ctrl-C (uvicorn's signal handling; the worker then
    stops any move and closes the rig)."""
    import uvicorn

    config = uvicorn.Config(build_app(options), log_level=log_level, ws="websockets-sansio", lifespan="on")
    server = uvicorn.Server(config)
    # uvicorn shuts down gracefully on SIGINT and SIGTERM only; a closed terminal or SSH
    # session sends SIGHUP, whose default would end the process with a stage still moving.
    signal.signal(signal.SIGHUP, lambda signum, frame: server.handle_exit(signal.SIGTERM, frame))
    server.run(sockets=[sock])
    sys.stdout.flush()


@contextlib.contextmanager
def serving_in_thread(
    options: ConsoleOptions, host: str = "127.0.0.1", port: int = 0, *, start_timeout_s: float = 60.0
):
    """Run the console in a background thread (tests, the benchmark); yields its URL. The
    rig worker is started by the app's lifespan and closed on the way out."""
    import threading

    import uvicorn

    sock = bind(host, port)
    server = uvicorn.Server(
        uvicorn.Config(build_app(options), log_level="warning", ws="websockets-sansio", lifespan="on")
    )
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, name="rig-console-server", daemon=True)
    thread.start()
    started = threading.Event()
    try:
        # uvicorn sets ``started`` from its loop; waiting on an event with a deadline, not sleeping
        while not server.started and thread.is_alive() and not started.wait(0.02):
            start_timeout_s -= 0.02
            if start_timeout_s <= 0:
                raise TimeoutError("the console server did not start")
        if not server.started:
            raise RuntimeError("the console server stopped while starting")
        yield url_of(sock, host, options.token)
    finally:
        server.should_exit = True
        thread.join(60.0)
        sock.close()
