"""The display's HTTP server: static page + ``config.json``, read-only, standard library only.

The page itself talks to the MQTT broker's WebSocket listener; this server never touches MQTT and never
holds broker credentials, so nothing secret can leak through the files it serves (docs/display.md).
"""

from __future__ import annotations

import json
import logging
import re
import threading
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from types import TracebackType
from typing import Any
from urllib.parse import urlsplit

from ...diagnosis.states import MotorState
from ...errors import ConfigError, LinkError
from .layout import FRAMES

__all__ = ["DisplayConfig", "DisplayServer", "state_kinds"]

log = logging.getLogger(__name__)

#: URL path → (file in ``static/``, content type). Nothing else is served.
STATIC_FILES: dict[str, tuple[str, str]] = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/display.js": ("display.js", "text/javascript; charset=utf-8"),
    "/display.css": ("display.css", "text/css; charset=utf-8"),
    "/mqtt.js": ("mqtt.js", "text/javascript; charset=utf-8"),
    "/hexaview.js": ("hexaview.js", "text/javascript; charset=utf-8"),
    "/hexaview.css": ("hexaview.css", "text/css; charset=utf-8"),
}

# Scripts and styles only from this server, the broker only over ws/wss, no framing, no form posts.
SECURITY_HEADERS = {
    "Content-Security-Policy": (
        "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
        "connect-src 'self' ws: wss:; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    ),
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-cache",
}

_PREFIX = re.compile(r"^[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*$")


def state_kinds() -> dict[str, dict[str, Any]]:
    """Every announced state label → how the page draws it (``ok``, ``fault``, ``sensor``, ``nodata``)."""
    kinds: dict[str, dict[str, Any]] = {}
    for state in MotorState:
        if state is MotorState.NORMAL:
            kind = "ok"
        elif state is MotorState.NO_DATA:
            kind = "nodata"
        elif state.is_fault:
            kind = "fault"
        else:  # SENSOR_FAULT: the signal, not the motor, is suspect
            kind = "sensor"
        kinds[state.label] = {"code": int(state), "description": state.description, "kind": kind}
    return kinds


def static_text(name: str) -> str:
    """One of the page's files, read from the installed package."""
    return resources.files(__package__).joinpath("static").joinpath(name).read_text(encoding="utf-8")


@dataclass(frozen=True)
class DisplayConfig:
    """What the page needs to know; served as ``config.json``. Holds no secret by construction.

    ``broker_ws_url`` None: the page connects to ``ws://<the host it was loaded from>:<default_ws_port>``
    (``wss`` when the page came over https).
    """

    broker_ws_url: str | None = None
    topic_prefix: str = "mmh"
    stale_after_s: float = 10.0
    chart_window_s: float = 60.0
    default_ws_port: int = 9001
    ask_credentials: bool = False
    keepalive_s: int = 20

    def __post_init__(self) -> None:
        if self.broker_ws_url is not None:
            parts = urlsplit(self.broker_ws_url)
            if parts.scheme not in ("ws", "wss") or not parts.hostname:
                raise ConfigError(
                    f"broker WebSocket URL {self.broker_ws_url!r} is not usable",
                    key="broker_ws_url",
                    expected="ws://host:port or wss://host:port",
                )
            if parts.username is not None or parts.password is not None:
                raise ConfigError(
                    "the broker URL holds credentials; they would be served to every viewer",
                    key="broker_ws_url",
                    expected="a URL without user:password@ (viewers log in on the page, or the broker "
                    "grants anonymous read-only access)",
                )
        if not _PREFIX.match(self.topic_prefix):
            raise ConfigError(
                f"topic prefix {self.topic_prefix!r} is not usable",
                key="topic_prefix",
                expected="topic levels of letters, digits, '_' or '-' separated by '/', no wildcards",
            )
        if not self.stale_after_s > 0 or not self.chart_window_s > 0:
            raise ConfigError(
                "stale_after_s and chart_window_s must be positive", expected="a number of seconds > 0"
            )
        if not 2 <= self.keepalive_s <= 3600:
            raise ConfigError(
                f"keep-alive {self.keepalive_s} s out of range", key="keepalive_s", expected="2..3600"
            )
        if not 0 < self.default_ws_port < 65536:
            raise ConfigError(f"port {self.default_ws_port} out of range", expected="1..65535")

    def to_json(self) -> dict[str, Any]:
        from ... import __version__

        return {
            "broker_ws_url": self.broker_ws_url,
            "topic_prefix": self.topic_prefix,
            "stale_after_s": self.stale_after_s,
            "chart_window_s": self.chart_window_s,
            "default_ws_port": self.default_ws_port,
            "ask_credentials": self.ask_credentials,
            "keepalive_s": self.keepalive_s,
            "default_frame": "hexa-x",
            "layouts": {name: [m.to_dict() for m in layout] for name, layout in FRAMES.items()},
            "states": state_kinds(),
            "version": __version__,
        }


class _Handler(BaseHTTPRequestHandler):
    server_version = "mav-motor-health-display"
    sys_version = ""
    config_json: bytes = b"{}"

    def do_GET(self) -> None:
        self._serve(body=True)

    def do_HEAD(self) -> None:
        self._serve(body=False)

    def _refuse(self) -> None:
        self.send_response(HTTPStatus.METHOD_NOT_ALLOWED)
        self.send_header("Allow", "GET, HEAD")
        self.send_header("Content-Length", "0")
        self.end_headers()

    do_POST = do_PUT = do_DELETE = do_PATCH = _refuse

    def _serve(self, *, body: bool) -> None:
        path = urlsplit(self.path).path
        if path == "/config.json":
            data, ctype = self.config_json, "application/json"
        elif path in STATIC_FILES:
            name, ctype = STATIC_FILES[path]
            data = static_text(name).encode("utf-8")
        else:
            data, ctype = b"not found\n", "text/plain; charset=utf-8"
            self.send_response(HTTPStatus.NOT_FOUND)
            self._headers(ctype, len(data))
            if body:
                self.wfile.write(data)
            return
        self.send_response(HTTPStatus.OK)
        self._headers(ctype, len(data))
        if body:
            self.wfile.write(data)

    def _headers(self, ctype: str, length: int) -> None:
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(length))
        for key, value in SECURITY_HEADERS.items():
            self.send_header(key, value)
        self.end_headers()

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("%s %s", self.address_string(), format % args)


class DisplayServer:
    """Serves the display page on ``host:port`` (port 0: any free one) from a background thread.

    A context manager: the server runs inside ``with`` and is shut down on exit. ``serve_forever()``
    instead blocks the calling thread (the CLI).
    """

    def __init__(self, config: DisplayConfig, host: str = "127.0.0.1", port: int = 8080) -> None:
        self.config = config
        handler = type("DisplayHandler", (_Handler,), {"config_json": json.dumps(config.to_json()).encode()})
        try:
            self._httpd = ThreadingHTTPServer((host, port), handler)
        except OSError as exc:
            raise LinkError(f"cannot serve the display on {host}:{port}: {exc.strerror or exc}") from exc
        self._httpd.daemon_threads = True
        self._thread: threading.Thread | None = None

    @property
    def address(self) -> tuple[str, int]:
        host, port = self._httpd.server_address[:2]
        return str(host), int(port)

    @property
    def url(self) -> str:
        host, port = self.address
        shown = f"[{host}]" if ":" in host else host
        return f"http://{shown}:{port}/"

    def serve_forever(self) -> None:
        try:
            self._httpd.serve_forever(poll_interval=0.25)
        finally:
            self._httpd.server_close()

    def __enter__(self) -> DisplayServer:
        self._thread = threading.Thread(
            target=self._httpd.serve_forever, kwargs={"poll_interval": 0.1}, name="display-http", daemon=True
        )
        self._thread.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._httpd.shutdown()
        self._httpd.server_close()
        if self._thread is not None:
            self._thread.join(timeout=5)
