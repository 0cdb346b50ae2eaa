"""Every request needs the server's token; no request from a foreign page.

The token comes once in the URL the server prints (`?token=...`, as Jupyter does): the
page is then sent back without it and the token kept in a cookie (HttpOnly,
SameSite=Strict, so another site's page never sends it). Scripts send it as
`Authorization: Bearer TOKEN`. A request whose Origin is not this server's own (or
that the browser marks cross-site) is refused with 403, whatever it carries: a page
elsewhere must not drive the machine through a browser that holds the cookie.
"""

from __future__ import annotations

import json
import secrets
from http.cookies import SimpleCookie
from urllib.parse import parse_qsl, urlencode

TOKEN_PARAMETER = "token"


def new_token() -> str:
    return secrets.token_urlsafe(24)


def cookie_name(port: int) -> str:
    """Cookies ignore the port: two servers on one host keep a cookie each."""
    return f"galileo_cnc_token_{port}"


class Guard:
    """ASGI middleware in front of the whole application."""

    def __init__(self, app, token: str, port: int, hosts: frozenset[str] | None = None):
        self.app = app
        self.token = token
        self.port = port
        self.hosts = hosts

    async def __call__(self, scope, receive, send):
        if scope["type"] == "lifespan":
            await self.app(scope, receive, send)
            return
        if scope["type"] != "http":     # no WebSocket route: refused before any handshake
            await send({"type": "websocket.close", "code": 1008})
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope["headers"]}
        if self.hosts is not None and _host_name(headers.get("host", "")) not in self.hosts:
            await _refuse(send, 403, "refused: the request is addressed to another host "
                                     "name than this computer's own (Host)")
            return
        if self._foreign(headers):
            await _refuse(send, 403, "refused: the request comes from another site's page "
                                     "(Origin)")
            return
        query = dict(parse_qsl(scope.get("query_string", b"").decode("latin-1")))
        given = query.get(TOKEN_PARAMETER)
        if given is not None and self._right(given) and scope["method"] in ("GET", "HEAD"):
            await self._keep_in_cookie(scope, query, send)
            return
        # the URL's token only opens the page: a command carries it in a header or the
        # cookie (a URL is kept in histories and logs)
        if not self._right(self._sent_token(headers)):
            await _refuse(send, 401, "the token is missing or wrong: open the URL "
                                     "galileo-cnc serve printed (it holds the token)")
            return
        await self.app(scope, receive, send)

    def _right(self, token: str | None) -> bool:
        return token is not None and secrets.compare_digest(token.encode(),
                                                            self.token.encode())

    def _sent_token(self, headers: dict) -> str | None:
        auth = headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            return auth[7:].strip()
        cookie = SimpleCookie()
        try:
            cookie.load(headers.get("cookie", ""))
        except Exception:               # a malformed cookie header: no token in it
            return None
        morsel = cookie.get(cookie_name(self.port))
        return morsel.value if morsel is not None else None

    @staticmethod
    def _foreign(headers: dict) -> bool:
        if headers.get("sec-fetch-site") == "cross-site":
            return True
        origin = headers.get("origin")
        if origin is None:              # curl, or a browser's same-origin GET
            return False
        host = headers.get("host", "")
        return origin not in (f"http://{host}", f"https://{host}")

    async def _keep_in_cookie(self, scope, query: dict, send) -> None:
        """The token from the URL into the cookie; the same address again without it
        (it leaves the address bar and the history)."""
        rest = {k: v for k, v in query.items() if k != TOKEN_PARAMETER}
        location = scope.get("root_path", "") + scope["path"] + (
            f"?{urlencode(rest)}" if rest else "")
        cookie = (f"{cookie_name(self.port)}={self.token}; Path=/; HttpOnly; "
                  f"SameSite=Strict")
        await send({"type": "http.response.start", "status": 303,
                    "headers": [(b"location", location.encode("latin-1")),
                                (b"set-cookie", cookie.encode("latin-1")),
                                (b"content-length", b"0")]})
        await send({"type": "http.response.body", "body": b""})


def _host_name(host: str) -> str:
    """`127.0.0.1:8765` -> `127.0.0.1`, `[::1]:8765` -> `::1`."""
    if host.startswith("["):
        return host[1:].partition("]")[0]
    return host.rpartition(":")[0] if host.count(":") == 1 else host


async def _refuse(send, status: int, text: str) -> None:
    body = json.dumps({"error": text}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})
