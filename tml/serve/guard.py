"""What keeps browsers and oversized requests from being turned against ``tml serve``.

Theory of operation
-------------------
A web page the operator opens in a browser can send requests to the service: to
``127.0.0.1`` directly (a cross-site request), or to a name of its own that it then points
at ``127.0.0.1`` (DNS rebinding: the browser takes the service for the page's own site).
Without a token nothing else stands in the way, and a form posted from another site could
fly or abort a vehicle. :class:`Guard`, an ASGI middleware in front of every route,
refuses such requests before any of the service sees them:

- *Host allow-list* (every request): the ``Host`` header must name the service as its
  operator reaches it -- ``localhost``, a loopback address, the address it is bound to
  (any address when it is bound to all of them: a DNS-rebinding page always comes by a
  name), or one of the names given with ``--allow-host``. Otherwise 400.
- *Origin* (every request that changes something: POST, PUT, PATCH, DELETE): a browser
  names the page a request comes from; it must be the service's own page (``Origin``
  with the request's own host and port, ``Sec-Fetch-Site`` same-origin). Otherwise 403.
  A program such as curl sends neither and is let through (with a token when there is
  one).
- *Body types* of a POST (the one write a page may send to another site without the
  browser asking that site first): JSON (the mission upload also XML or a multipart form);
  a form's own encodings (``application/x-www-form-urlencoded``, ``text/plain``) are 415.
  JSON and XML cannot be sent across sites without the browser asking the service first,
  which it never allows (it answers no CORS).
- *Body size*: at most ``max_body`` bytes, on every route: a larger ``Content-Length`` is
  refused at once, a longer chunked body as soon as it passes the limit (413).
- *Headers* on every answer: a Content-Security-Policy allowing only the page's own files
  (no inline script; images also from the one tile server of ``--tile-url``) and no
  framing, ``X-Frame-Options: DENY``, ``X-Content-Type-Options: nosniff``,
  ``Referrer-Policy: no-referrer``.
"""

from __future__ import annotations

import ipaddress
import json
from collections.abc import Awaitable, Callable, Iterable, MutableMapping
from typing import Any
from urllib.parse import urlsplit

from starlette.exceptions import HTTPException

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

MAX_BODY = 4 * 1024 * 1024  # bytes of a request body, by default (--max-body)
WRITES = frozenset({"POST", "PUT", "PATCH", "DELETE"})
UPLOADS = frozenset({"application/xml", "text/xml", "multipart/form-data"})
POLICY = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
          "connect-src 'self'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'")
HEADERS = [(b"content-security-policy", POLICY.encode()), (b"x-frame-options", b"DENY"),
           (b"x-content-type-options", b"nosniff"), (b"referrer-policy", b"no-referrer"),
           (b"cross-origin-resource-policy", b"same-origin")]


def headers(images: str | None = None) -> list[tuple[bytes, bytes]]:
    """The security headers of every answer; ``images``: the one more origin the page may
    load images from (the tile server of ``--tile-url``), besides the service itself."""
    if images is None:
        return HEADERS
    policy = POLICY.replace("img-src 'self' data:;", f"img-src 'self' data: {images};")
    return [(b"content-security-policy", policy.encode()), *HEADERS[1:]]
WILDCARDS = ("0.0.0.0", "::", "")


class BodyTooLarge(HTTPException):
    """A request body longer than the limit, found while it is read (answered 413 by the
    API's handler of HTTP errors, or here when it gets this far)."""

    def __init__(self, limit: int) -> None:
        super().__init__(413, f"a request body is at most {limit} bytes (--max-body)")


class Guard:
    """The middleware; see the module docstring. ``bound``: the address the service is
    bound to; ``hosts``: more names it may be called by; ``max_body``: the largest body
    taken, in bytes; ``images``: an origin images may come from besides the service."""

    def __init__(self, app: ASGIApp, bound: str = "127.0.0.1", hosts: Iterable[str] = (),
                 max_body: int = MAX_BODY, images: str | None = None) -> None:
        self.app = app
        self.headers = headers(images)
        self.bound = bound.strip("[]").lower()
        self.hosts = {"localhost"} | {_plain_host(h) for h in hosts}
        self.max_body = max_body

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1")
                   for k, v in scope.get("headers", ())}
        refusal = self.refusal(str(scope.get("method", "GET")).upper(),
                               str(scope.get("path", "")), headers)
        if refusal is not None:
            await _answer(send, *refusal, self.headers)
            return
        started = False

        async def send_with_headers(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                names = {k.lower() for k, _ in message.get("headers", ())}
                message["headers"] = [*message.get("headers", ()),
                                      *[(k, v) for k, v in self.headers if k not in names]]
            await send(message)

        read = 0

        async def bounded() -> Message:
            nonlocal read
            message = await receive()
            if message["type"] == "http.request":
                read += len(message.get("body", b""))
                if read > self.max_body:
                    raise BodyTooLarge(self.max_body)
            return message

        try:
            await self.app(scope, bounded, send_with_headers)
        except BodyTooLarge:
            if started:
                raise
            await _answer(send, *self.too_large(), self.headers)

    def refusal(self, method: str, path: str,
                headers: dict[str, str]) -> tuple[int, str] | None:
        """Why a request is refused (status, message), or None."""
        host = headers.get("host", "")
        if not self.allowed_host(host):
            return 400, (f"this service is not {_plain_host(host) or 'a nameless host'!r}: "
                         "call it by its address or localhost (or start it with "
                         "--allow-host NAME)")
        length = headers.get("content-length", "")
        if length.strip().isdigit() and int(length) > self.max_body:
            return self.too_large()
        if method not in WRITES:
            return None
        site = headers.get("sec-fetch-site", "").lower()
        origin = headers.get("origin")
        if site not in ("", "same-origin", "none"):
            return 403, f"refused: a {site} request from a browser page"
        if origin is not None and not _same_origin(origin, host):
            return 403, "refused: a request from another site's page (Origin " \
                        f"{origin[:100]!r})"
        # Only POST can be sent from another site without the browser asking first (PUT,
        # PATCH and DELETE are asked about, and refused: no CORS).
        kind = headers.get("content-type", "").split(";")[0].strip().lower()
        if method == "POST" and kind and kind != "application/json" and not (
                kind in UPLOADS and path.rstrip("/") == "/missions"):
            if path.rstrip("/") == "/missions":
                return 415, ("send the mission as application/xml, or as a "
                             "multipart/form-data field named 'file'")
            return 415, f"a body of type {kind[:100]!r} is not taken here: send JSON"
        return None

    def allowed_host(self, host: str) -> bool:
        """Whether ``host`` (a Host header) names this service."""
        name = _plain_host(host)
        if not name:
            return False
        if name in self.hosts or name == self.bound:
            return True
        try:
            address = ipaddress.ip_address(name)
        except ValueError:
            return False
        return address.is_loopback or self.bound in WILDCARDS

    def too_large(self) -> tuple[int, str]:
        """The refusal of a body over the limit."""
        return 413, f"a request body is at most {self.max_body} bytes (--max-body)"


def _plain_host(host: str) -> str:
    """A Host header's name or address, lower case, without port, brackets or final dot."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1:].split("]", 1)[0]
    if host.count(":") == 1:
        host = host.split(":", 1)[0]
    return host.rstrip(".")


def _same_origin(origin: str, host: str) -> bool:
    """Whether an Origin header names the site the request was sent to (its Host)."""
    try:
        found = urlsplit(origin.strip())
    except ValueError:
        return False
    return found.scheme in ("http", "https") and bool(found.netloc) and \
        found.netloc.lower() == host.strip().lower() and not found.path.strip("/")


async def _answer(send: Send, status: int, message: str,
                  security: list[tuple[bytes, bytes]]) -> None:
    body = json.dumps({"error": message}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close"), *security]})
    await send({"type": "http.response.body", "body": body})
