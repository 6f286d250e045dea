"""The live view's HTTP server: standard library only, 127.0.0.1 only.

GET  /              the page (static/index.html), /view.js its script
GET  /info.json     what does not change: arena, home, states and colours
GET  /state.json    the source's state now (the page polls it)
GET  /robot.json?node=N  one robot for the inspector (a simulated run)
GET  /favicon.svg   the tab's icon (also at /favicon.ico)
POST /control/ACTION  play, pause, step ({"ticks": n}), speed
                    ({"ticks_per_second": x}), reset ({"set": ["KEY=VALUE", ...],
                    "seed": n}); the answer is the run's summary
A bad request gets 400 and {"error": "<one line>"}.
"""

from __future__ import annotations

import errno
import json
import logging
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

from bridge.errors import UsageError
from bridge.view.sources import BadRequest

log = logging.getLogger(__name__)

HOST = "127.0.0.1"
MAX_BODY = 4096         # a control request is a few bytes of JSON
STATIC = {"/": ("index.html", "text/html; charset=utf-8"),
          "/view.js": ("view.js", "text/javascript; charset=utf-8"),
          "/favicon.svg": ("favicon.svg", "image/svg+xml"),
          "/favicon.ico": ("favicon.svg", "image/svg+xml")}


class Handler(BaseHTTPRequestHandler):
    server: "ViewServer"

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("%s " + format, self.address_string(), *args)

    def _send(self, code: int, body: bytes, ctype: str) -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):
            # the page went away mid-answer (a closed tab, a screenshot's browser quitting)
            log.debug("%s went away before the answer", self.address_string())

    def _json(self, code: int, obj: Any) -> None:
        self._send(code, json.dumps(obj).encode(), "application/json")

    def _error(self, code: int, text: str) -> None:
        self._json(code, {"error": text.splitlines()[0] if text else "error"})

    def do_GET(self) -> None:
        path = self.path.split("?", 1)[0]
        source = self.server.source
        if path in STATIC:
            name, ctype = STATIC[path]
            self._send(200, resources.files("bridge.view").joinpath("static", name).read_bytes(),
                       ctype)
        elif path == "/info.json":
            self._json(200, source.info())
        elif path == "/state.json":
            try:
                state = source.state()
            except Exception as err:       # the page shows it and keeps polling
                log.exception("state of the live view")
                self._error(500, f"{type(err).__name__}: {err}")
                return
            self._json(200, state)
        elif path == "/robot.json":
            try:
                self._json(200, self._robot())
            except BadRequest as err:
                self._error(400, str(err))
        else:
            self._error(404, f"no such page {path}")

    def _robot(self) -> dict[str, Any]:
        from urllib.parse import parse_qs, urlsplit
        robot = getattr(self.server.source, "robot", None)
        if robot is None:
            raise BadRequest("robot: the journal source has no robot inspector (the host "
                             "knows only each robot's last HEARTBEAT)")
        node = parse_qs(urlsplit(self.path).query).get("node", [""])[0]
        if not node.isdigit():
            raise BadRequest(f"robot: node must be a robot number, got {node!r}")
        return robot(int(node))

    def do_POST(self) -> None:
        path = self.path.split("?", 1)[0]
        if not path.startswith("/control/"):
            self._error(404, f"no such endpoint {path}")
            return
        try:
            body = self._body()
            self._json(200, self.server.source.control(path[len("/control/"):], body))
        except BadRequest as err:
            self._error(400, str(err))

    def _body(self) -> dict[str, Any]:
        try:
            size = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise BadRequest("Content-Length is not a number") from None
        if not 0 <= size <= MAX_BODY:
            raise BadRequest(f"request body of {size} bytes (at most {MAX_BODY})")
        raw = self.rfile.read(size) if size else b""
        if not raw.strip():
            return {}
        try:
            body = json.loads(raw)
        except ValueError as err:
            raise BadRequest(f"request body is not JSON: {err}") from None
        if not isinstance(body, dict):
            raise BadRequest("request body must be a JSON object")
        return body


class ViewServer(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, source: Any, port: int = 0) -> None:
        self.source = source
        try:
            super().__init__((HOST, port), Handler)
        except OSError as err:
            if err.errno == errno.EADDRINUSE:
                raise UsageError(f"--port {port}: address already in use on {HOST}") from None
            if err.errno == errno.EACCES:
                raise UsageError(f"--port {port}: permission denied on {HOST}") from None
            raise
        self.thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server_address[1]}/"

    def start(self) -> "ViewServer":
        """Serve in a background thread (tests, screenshots)."""
        self.thread = threading.Thread(target=self.serve_forever, name="view-http", daemon=True)
        self.thread.start()
        return self

    def stop(self) -> None:
        if self.thread is not None:
            self.shutdown()
            self.thread.join()
        self.server_close()
        self.source.close()
