"""The web server: uvicorn serving the application on a socket of ours, so that the
URL with its token is printed with the port really bound (`--listen HOST:0` takes a
free one), and tests run the very same server in a thread.
"""

from __future__ import annotations

import socket
import threading

import uvicorn

from galileo_cnc.errors import GalileoError
from galileo_cnc.serve.app import create_app
from galileo_cnc.serve.guard import new_token
from galileo_cnc.serve.service import MachineService

DEFAULT_LISTEN = "127.0.0.1:8765"
LOOPBACK = ("127.0.0.1", "::1", "localhost")
#: the host names a request to a server on loopback may be addressed to
LOOPBACK_NAMES = frozenset(LOOPBACK)


def parse_listen(text: str) -> tuple[str, int]:
    """`HOST:PORT` (`[::1]:8765` for IPv6; `:8765` listens everywhere)."""
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit() or int(port) > 65535:
        raise GalileoError(f"--listen: expected HOST:PORT (e.g. 127.0.0.1:8765, or "
                           f"0.0.0.0:8765 for every interface), got {text!r}")
    host = host.strip("[]") or "0.0.0.0"
    return host, int(port)


class WebServer:
    def __init__(self, service: MachineService, host: str = "127.0.0.1", port: int = 8765,
                 token: str | None = None):
        self.service = service
        try:
            self.sock = _listening_socket(host, port)
        except OSError as error:
            raise GalileoError(f"--listen {host}:{port}: {error.strerror or error}") from None
        self.host = host
        self.port = self.sock.getsockname()[1]
        self.token = token or new_token()
        # on loopback only loopback names: a name of another site's that resolves here
        # (DNS rebinding) is refused whatever it carries
        self.app = create_app(service, self.token, self.port,
                              hosts=None if self.everywhere else LOOPBACK_NAMES)
        # held streams (the event stream) end with the server: don't wait for them
        self.server = _Server(uvicorn.Config(
            self.app, log_level="warning", lifespan="off", timeout_graceful_shutdown=2),
            on_exit=service.closing.set)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = self.host if self.host not in ("0.0.0.0", "::") else socket.gethostname()
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.port}/?token={self.token}"

    @property
    def everywhere(self) -> bool:
        return self.host not in LOOPBACK

    def run(self) -> None:
        """Until Ctrl-C (uvicorn's signal handling)."""
        self.server.run(sockets=[self.sock])

    def start(self) -> "WebServer":
        """In a thread of its own (tests); returns once it answers."""
        self._thread = threading.Thread(target=self.run, name="galileo-web", daemon=True)
        self._thread.start()
        while not self.server.started:
            if not self._thread.is_alive():
                raise GalileoError("the web server did not start")
            self._thread.join(0.01)
        return self

    def shutdown(self) -> None:
        self.server.on_exit()
        self.server.should_exit = True
        if self._thread is not None:
            self._thread.join(10)
        self.sock.close()


def _listening_socket(host: str, port: int) -> socket.socket:
    """Made with IPPROTO_TCP named: asyncio sets TCP_NODELAY only on such sockets' peers
    (socket.create_server's proto 0 leaves Nagle on: 40 ms per kept-alive request)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(128)
    except OSError:
        sock.close()
        raise
    return sock


class _Server(uvicorn.Server):
    """Ctrl-C ends the held streams too (else the server waits for the pages)."""

    def __init__(self, config, on_exit):
        super().__init__(config)
        self.on_exit = on_exit

    def handle_exit(self, sig, frame) -> None:
        self.on_exit()
        super().handle_exit(sig, frame)
