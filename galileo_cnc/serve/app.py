"""The Starlette application: the page, the JSON API and the event stream.

Every route sits behind guard.Guard (the token, the Origin). Handlers never wait on
the port: machine commands go to the service's worker thread, planning to the thread
pool. The API is documented in docs/serve.md.
"""

from __future__ import annotations

import asyncio
import json
import math
import threading
from importlib import resources

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from galileo_cnc.errors import GalileoError
from galileo_cnc.serve.guard import Guard
from galileo_cnc.serve.jog import AXES
from galileo_cnc.serve.service import Busy, MachineService, NotFound
from galileo_cnc.serve.uploads import UploadRefused, display_name, too_large

#: how often a held response sends something (an SSE comment, a jog's position)
HEARTBEAT_S = 10.0
CLOSING_CHECK_S = 0.5
JOG_REPORT_S = 0.1
PAGE_FILES = {"/": ("index.html", "text/html; charset=utf-8"),
              "/app.js": ("app.js", "text/javascript; charset=utf-8"),
              "/app.css": ("app.css", "text/css; charset=utf-8")}


def create_app(service: MachineService, token: str, port: int,
               hosts: frozenset[str] | None = None) -> Guard:
    """The application with the guard in front (`port`: the cookie's name; `hosts`: the
    host names a request may be addressed to, None for any)."""
    routes = [
        Route("/", page), Route("/app.js", page), Route("/app.css", page),
        Route("/api/state", state),
        Route("/api/events", events),
        Route("/api/history", history),
        Route("/api/uploads", upload, methods=["POST"]),
        Route("/api/plans", make_plan, methods=["POST"]),
        Route("/api/plans/{plan_id}", get_plan),
        Route("/api/plans/{plan_id}/preview.svg", preview),
        Route("/api/jobs", start_job, methods=["POST"]),
        Route("/api/stop", stop, methods=["POST"]),
        Route("/api/resume", resume, methods=["POST"]),
        Route("/api/prompt", answer, methods=["POST"]),
        Route("/api/jog", jog, methods=["POST"]),
        Route("/api/feed", feed, methods=["POST"]),
        Route("/api/home", home, methods=["POST"]),
        Route("/api/unlock", unlock, methods=["POST"]),
    ]
    app = Starlette(routes=routes, exception_handlers={GalileoError: _error,
                                                       HTTPException: _http_error})
    app.state.service = service
    return Guard(app, token, port, hosts)


async def _error(request: Request, error: Exception) -> JSONResponse:
    status = (error.status if isinstance(error, UploadRefused) else
              409 if isinstance(error, Busy) else 404 if isinstance(error, NotFound) else 422)
    return JSONResponse({"error": str(error)}, status_code=status)


async def _http_error(request: Request, error: HTTPException) -> JSONResponse:
    """No such route, or not with that method: JSON too, as every other answer."""
    return JSONResponse({"error": f"{request.method} {request.url.path}: {error.detail}"},
                        status_code=error.status_code, headers=error.headers)


def _service(request: Request) -> MachineService:
    return request.app.state.service


async def _json(request: Request) -> dict:
    try:
        data = await request.json()
    except ValueError:
        raise GalileoError("the request's body is not JSON") from None
    if not isinstance(data, dict):
        raise GalileoError("the request's body must be a JSON object")
    return data


async def page(request: Request) -> Response:
    name, media = PAGE_FILES[request.url.path]
    body = resources.files("galileo_cnc.serve").joinpath("page", name).read_bytes()
    return Response(body, media_type=media, headers={
        "cache-control": "no-store", "x-content-type-options": "nosniff",
        "content-security-policy": "default-src 'self'; img-src 'self' data:; "
                                   "style-src 'self' 'unsafe-inline'; frame-ancestors 'none'"})


async def state(request: Request) -> JSONResponse:
    return JSONResponse(_service(request).snapshot())


async def history(request: Request) -> JSONResponse:
    return JSONResponse({"history": _service(request).history})


async def upload(request: Request) -> JSONResponse:
    """The body is the file (any content type); `X-Filename` its name, for showing."""
    service = _service(request)
    limit = service.store.max_bytes
    length = request.headers.get("content-length")
    if length is not None and length.isdigit() and int(length) > limit:
        raise too_large(limit)
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise too_large(limit)
        chunks.append(chunk)
    name = display_name(request.headers.get("x-filename"))
    kept = await asyncio.to_thread(service.store.keep, b"".join(chunks), name)
    return JSONResponse(kept.public(), status_code=201)


#: what POST /api/plans takes
PLAN_FIELDS = frozenset({"upload", "pens", "mode", "side", "offset", "allow_open", "mill",
                         "mill_set", "accept_shorts"})


async def make_plan(request: Request) -> JSONResponse:
    """{upload, pens?, mode?, side?, offset?, allow_open?}: planned, its preview drawn;
    with {mill: isolate|drill|cutout|all, mill_set?, accept_shorts?} a mill job."""
    data = await _json(request)
    unknown = sorted(set(data) - PLAN_FIELDS)
    if unknown:        # a misspelt option would be planned without, unsaid
        raise GalileoError(f"plan: unknown field {unknown[0]!r}; the fields are "
                           f"{', '.join(sorted(PLAN_FIELDS))}")
    service = _service(request)
    plan = await asyncio.to_thread(
        service.plan, str(data.get("upload") or ""), pens=str(data.get("pens") or ""),
        mode=str(data.get("mode") or "auto"), side=str(data.get("side") or "top"),
        offset=str(data.get("offset") or "auto"), allow_open=bool(data.get("allow_open")),
        mill=str(data.get("mill") or ""), mill_set=data.get("mill_set") or {},
        accept_shorts=data.get("accept_shorts") is True)
    return JSONResponse(plan.public(), status_code=201)


async def get_plan(request: Request) -> JSONResponse:
    return JSONResponse(_service(request).get_plan(request.path_params["plan_id"]).public())


async def preview(request: Request) -> Response:
    plan = _service(request).get_plan(request.path_params["plan_id"])
    if plan.preview is None:
        raise NotFound(f"plan {plan.id} is a mill job: it has no preview")
    body = await asyncio.to_thread(plan.preview.read_bytes)
    return Response(body, media_type="image/svg+xml",
                    headers={"content-security-policy": "default-src 'none'; "
                                                        "style-src 'unsafe-inline'"})


async def start_job(request: Request) -> JSONResponse:
    data = await _json(request)
    _service(request).start(str(data.get("plan", "")))
    return JSONResponse({"started": True}, status_code=202)


async def stop(request: Request) -> JSONResponse:
    return JSONResponse({"stopping": _service(request).stop()})


async def resume(request: Request) -> JSONResponse:
    _service(request).resume()
    return JSONResponse({"resuming": True}, status_code=202)


async def answer(request: Request) -> JSONResponse:
    data = await _json(request)
    try:
        prompt_id = int(data.get("id"))
    except (TypeError, ValueError):
        raise GalileoError("prompt: expected {\"id\": N, \"answer\": true|false}") from None
    _service(request).answer(prompt_id, bool(data.get("answer", True)))
    return JSONResponse({"answered": prompt_id})


async def _done(future) -> JSONResponse:
    lines = await asyncio.wrap_future(future)
    return JSONResponse({"said": lines})


async def home(request: Request) -> JSONResponse:
    return await _done(_service(request).home())


async def unlock(request: Request) -> JSONResponse:
    return await _done(_service(request).unlock())


async def feed(request: Request) -> JSONResponse:
    data = await _json(request)
    mm_s = data.get("mm_s")
    if isinstance(mm_s, bool) or not isinstance(mm_s, (int, float)) or \
            not math.isfinite(mm_s):
        raise GalileoError(f"feed: expected {{\"mm_s\": N}}, a number of mm/s, got "
                           f"{json.dumps(mm_s)}")
    return await _done(_service(request).set_feed(mm_s))


async def jog(request: Request) -> Response:
    """{axis: x|y|z, direction: 1|-1, distance_mm?}: with a distance, one step (the
    answer comes when the head stands); without, held: the answer is a stream of
    positions (a JSON line each JOG_REPORT_S) until the client closes it, which stops
    the head."""
    data = await _json(request)
    axis_name = str(data.get("axis", "")).lower()
    direction = data.get("direction")
    if axis_name not in AXES or isinstance(direction, bool) or direction not in (1, -1):
        raise GalileoError("jog: expected {\"axis\": \"x\"|\"y\"|\"z\", \"direction\": 1|-1}")
    distance = data.get("distance_mm")
    if distance is not None:
        if isinstance(distance, bool) or not isinstance(distance, (int, float)):
            raise GalileoError(f"jog: distance_mm must be a number of mm, got "
                               f"{json.dumps(distance)}")
        if not 0 < distance <= 1000:
            raise GalileoError("jog: distance_mm must be above 0 and at most 1000")
        distance = float(distance)
    service = _service(request)
    cancelled = threading.Event()
    future = service.jog_session(AXES.index(axis_name), data["direction"], cancelled,
                                 distance)
    if distance is not None:
        return await _done(future)
    return HeldStream("application/x-ndjson", _jog_lines(service, future),
                      on_close=cancelled.set)


async def _jog_lines(service: MachineService, future):
    while not future.done():
        yield json.dumps(service.snapshot_position()) + "\n"
        await asyncio.sleep(JOG_REPORT_S)
    try:
        said = future.result()
    except GalileoError as error:
        said = [str(error)]
    yield json.dumps({**service.snapshot_position(), "said": said}) + "\n"


async def events(request: Request) -> Response:
    """Server-sent events: `state` first (everything), then status, progress, prompt,
    message, error, job and activity events as they happen."""
    service = _service(request)
    queue = service.subscribe()

    async def stream():
        yield _sse({"type": "state", **service.snapshot()})
        quiet_s = 0.0
        while not service.closing.is_set():     # the server ends: so does the stream
            try:
                event = await asyncio.wait_for(queue.get(), CLOSING_CHECK_S)
            except asyncio.TimeoutError:
                quiet_s += CLOSING_CHECK_S
                if quiet_s >= HEARTBEAT_S:
                    quiet_s = 0.0
                    yield ": still here\n\n"
                continue
            yield _sse(event)
    return HeldStream("text/event-stream", stream(),
                      on_close=lambda: service.unsubscribe(queue))


def _sse(event: dict) -> str:
    return f"event: {event['type']}\ndata: {json.dumps(event)}\n\n"


class HeldStream(Response):
    """A response that streams until its client goes away, and knows at once when it
    does (the `http.disconnect` message): `on_close` runs then, or when the stream
    ends. Starlette's StreamingResponse would only notice at its next write."""

    def __init__(self, media_type: str, chunks, on_close):
        self.chunks = chunks
        self.on_close = on_close
        self.status_code = 200
        self.media_type = media_type
        self.background = None
        self.init_headers({"cache-control": "no-store", "x-accel-buffering": "no"})

    async def __call__(self, scope, receive, send) -> None:
        async def pump():
            await send({"type": "http.response.start", "status": self.status_code,
                        "headers": self.raw_headers})
            async for chunk in self.chunks:
                await send({"type": "http.response.body", "body": chunk.encode(),
                            "more_body": True})
            await send({"type": "http.response.body", "body": b"", "more_body": False})

        async def gone():
            while (await receive())["type"] != "http.disconnect":
                pass

        tasks = [asyncio.ensure_future(pump()), asyncio.ensure_future(gone())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            self.on_close()
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
