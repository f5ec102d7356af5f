"""The HTTP API of ``tml serve`` (FastAPI) and the page it serves.

Theory of operation
-------------------
Each route is a thin shell over one :class:`~tml.serve.service.Service` call: it reads the
request, calls the service (in the thread pool when the call may take long or touch the
database), and answers JSON. The OpenAPI 3 document at ``/openapi.json`` is FastAPI's,
from the route declarations and the models below. docs/serve.md shows every route with
curl.

*Errors* are JSON, never a traceback: ``{"error": "what went wrong", ...}`` with the
status that says whose fault it is (400 a bad request or a host name the service does not
answer to, 401 no or a wrong token, 403 a write from another site's page, 404 no such
thing, 405 a method the route does not take (with ``Allow``), 409 a conflict with what is
going on, 413 a body over ``--max-body``, 415 a body of another type, 422 a valid request
the service refuses, with the diagnostics or the report that say why, 503 the database is
unreachable). An unexpected exception is logged here with its traceback and answered 500
with its one-line text.

*Browsers* (:mod:`tml.serve.guard`, in front of every route): a Host allow-list against
DNS rebinding, an Origin check and JSON-only bodies on writes against other sites' pages,
the body size limit, and the security headers of every answer.

*Auth.* With a token, every API route needs ``Authorization: Bearer TOKEN`` (compared in
constant time). The page's files and the OpenAPI document hold no data and are served to
anyone, so that a browser can load the page, which then asks for the token; so are the
map's tiles and their description (``/tiles``: a browser's image requests carry no token).

*Live updates* are Server-Sent Events: ``GET /runs/{id}/stream`` sends the run's flight
log lines, each as one ``record`` event whose data is the line (the JSON of ``tml run
--log``) and whose id is its number, from the first (or after ``Last-Event-ID``, so a
reconnecting client misses nothing) until the run ends, then one ``end`` event with the
run. The stream is fed by the run's thread through an asyncio queue per client.
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import sqlite3
from collections.abc import AsyncIterator, Awaitable, Callable, Sequence
from contextlib import asynccontextmanager
from importlib import resources
from typing import Any, Literal, ParamSpec, TypeVar

from fastapi import APIRouter, Depends, FastAPI, Header, Path, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, Response, StreamingResponse
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field
from sqlalchemy.exc import OperationalError
from sse_starlette.sse import EventSourceResponse
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.routing import Match

from tml import __version__
from tml.errors import TmlError
from tml.serve.answers import (
    CommandAnswer,
    MissionDetail,
    MissionSummary,
    RunView,
    ServiceStatus,
    VehicleView,
)
from tml.serve.guard import MAX_BODY, Guard
from tml.serve.service import RequestError, Service
from tml.serve.storage import StorageError
from tml.serve.tiles import TileSource
from tml.verify.report import report_document

LAST_RECORD = 2**31  # the highest record number asked for (after, Last-Event-ID)
METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")
T = TypeVar("T")
P = ParamSpec("P")
log = logging.getLogger("tml.serve")


# --- the documents -----------------------------------------------------------------------

class Problem(BaseModel):
    """An error answer."""

    model_config = ConfigDict(extra="allow")
    error: str = Field(description="what went wrong, in one sentence")


class VerifyRequest(BaseModel):
    """What to verify a mission against."""

    model_config = ConfigDict(extra="forbid")
    profile: Literal["quadcopter", "fixed-wing", "rover"] = "quadcopter"
    battery: float = Field(default=100.0, ge=0.0, le=100.0, description="charge at the start, %")


class RunRequest(BaseModel):
    """A run to start."""

    model_config = ConfigDict(extra="forbid")
    mission: str = Field(pattern=r"^[0-9a-f]{1,32}$", description="the mission's id")
    vehicles: list[int] | None = Field(
        default=None, max_length=1000,
        description="the vehicles to fly it (default: the first free one; with roles, "
                    "every free one)")
    safe_state: Literal["rtl", "land", "hold"] = "rtl"
    profile: Literal["quadcopter", "fixed-wing", "rover", "vehicle"] = Field(
        default="quadcopter", description="the verifier's profile: a shipped one, or vehicle: "
                                          "the first vehicle's kind filled in from its "
                                          "parameters (as tml run --profile vehicle)")
    force: bool = Field(default=False, description="fly even an infeasible mission")


class JumpRequest(BaseModel):
    """Where to jump."""

    model_config = ConfigDict(extra="forbid")
    task: str = Field(min_length=1, max_length=1000,
                      description="the task to go on from: its name, or its path "
                                  "(names joined by '/')")


class CommandRequest(BaseModel):
    """An operator's command to a vehicle."""

    model_config = ConfigDict(extra="forbid")
    command: Literal["rtl", "land", "hold", "disarm"] = Field(
        description="rtl: return to launch; land: land where it is; hold: stop where it is "
                    "(a multicopter hovers, a fixed-wing circles, a rover stops); disarm: "
                    "only on the ground")


class TileDescription(BaseModel):
    """Where the page's map tiles come from (``tml serve --tiles`` or ``--tile-url``)."""

    source: Literal["mbtiles", "url"] | None = Field(
        description="mbtiles: this service serves them; url: a tile server; null: none")
    url: str | None = Field(None, description="the template of a tile's URL, with {z}, {x} "
                                              "and {y} (rows counted from the north)")
    attribution: str | None = Field(None, description="who made the tiles (plain text)")
    minzoom: int | None = None
    maxzoom: int | None = None
    bounds: list[float] | None = Field(
        None, min_length=4, max_length=4,
        description="west, south, east, north in degrees, when the file says")


ERRORS: dict[int | str, dict[str, Any]] = {
    code: {"model": Problem, "description": text} for code, text in (
        (400, "a request that cannot be read, or sent to a host name the service does not "
              "answer to"), (401, "no token, or a wrong one"),
        (403, "sent by another site's page (Origin, Sec-Fetch-Site)"),
        (404, "not found"), (409, "conflicts with what is going on"),
        (413, "a body larger than --max-body"), (415, "a body of a type not taken here"),
        (422, "refused: invalid input, or a mission that is invalid or cannot be flown"),
        (503, "the database is unreachable"))}


# --- the application ---------------------------------------------------------------------

def create_app(service: Service, token: str | None = None, *, bound: str = "127.0.0.1",
               hosts: Sequence[str] = (), max_body: int = MAX_BODY,
               tiles: TileSource | None = None) -> FastAPI:
    """The ASGI application of ``service``; with ``token``, every API route needs it.
    ``bound`` is the address it is served on, ``hosts`` more names it may be called by,
    ``max_body`` the largest request body it takes (:class:`~tml.serve.guard.Guard`),
    ``tiles`` where the page's map tiles come from (:mod:`tml.serve.tiles`; none: the
    map is drawn in metres on a grid)."""
    tiles = tiles or TileSource()

    @asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        yield
        await run_in_threadpool(service.stop)

    app = FastAPI(title="tml serve", version=__version__, lifespan=lifespan,
                  docs_url=None, redoc_url=None,  # their pages load scripts from the internet
                  description="Fly TML missions on MAVLink vehicles: upload and verify "
                              "missions, run them, watch them live. See docs/serve.md.")
    _errors(app)
    app.add_middleware(Guard, bound=bound, hosts=hosts, max_body=max_body,
                       images=tiles.origin())

    def authorized(authorization: str | None = Header(
            None, description="Bearer TOKEN, when the service was started with a token")
                   ) -> None:
        if token is None:
            return
        scheme, _, given = (authorization or "").partition(" ")
        if scheme.lower() != "bearer" or not hmac.compare_digest(given.strip().encode(),
                                                                 token.encode()):
            raise HTTPException(401, "this service needs 'Authorization: Bearer TOKEN'",
                                headers={"WWW-Authenticate": "Bearer"})

    api = APIRouter(dependencies=[Depends(authorized)], responses=ERRORS)
    _missions(api, service, max_body)
    _runs(api, service)
    _vehicles(api, service)

    @api.get("/status", response_model=ServiceStatus, tags=["service"])
    def status() -> ServiceStatus:
        """The service: its instance name, storage backend, vehicles and live runs."""
        return service.status()

    app.include_router(api)
    _tiles(app, tiles)
    page = resources.files("tml.serve").joinpath("page")
    app.mount("/page", PageFiles(directory=str(page)), name="page")

    @app.get("/", include_in_schema=False)
    def index() -> FileResponse:
        return FileResponse(str(page.joinpath("index.html")), media_type="text/html",
                            headers={"Cache-Control": "no-cache"})

    return app


class PageFiles(StaticFiles):
    """The page's files, checked again (by their ETag) at every load: a browser never runs
    the script of one version of tml with the page of another."""

    def file_response(self, *args: Any, **kwargs: Any) -> Response:
        response = super().file_response(*args, **kwargs)
        response.headers["Cache-Control"] = "no-cache"
        return response


def _tiles(app: FastAPI, tiles: TileSource) -> None:
    """The map's tiles: served to anyone, as the page's files are (a browser's image
    requests carry no token)."""

    @app.get("/tiles", response_model=TileDescription, tags=["map"])
    def description() -> dict[str, Any]:
        """Where the page's map tiles come from: this service's MBTiles file, a tile
        server's URL template, or none (source null: the map is drawn in metres)."""
        return tiles.description()

    @app.get("/tiles/{z}/{x}/{y}", tags=["map"], response_class=Response, responses={
        200: {"content": {"image/png": {}, "image/jpeg": {}, "image/webp": {}},
              "description": "the tile"},
        404: {"model": Problem, "description": "no tile there, or no --tiles file"},
        503: {"model": Problem, "description": "the --tiles file cannot be read"}})
    async def tile(z: int = Path(ge=0, le=30), x: int = Path(ge=0),
                   y: int = Path(ge=0)) -> Response:
        """One tile of the ``--tiles`` MBTiles file: zoom ``z``, column ``x``, row ``y``
        counted from the north (as web maps count; the file's rows are flipped)."""
        try:
            found = await _call(tiles.tile, z, x, y)
        except sqlite3.Error as error:
            log.error("the tiles file %s cannot be read: %s", tiles.mbtiles, error)
            raise HTTPException(503, f"the tiles file cannot be read: {error}") from None
        if found is None:
            raise HTTPException(404, f"no tile {z}/{x}/{y}" if tiles.mbtiles else
                                "this service serves no tiles (no --tiles file)")
        data, media_type = found
        return Response(data, media_type=media_type,
                        headers={"Cache-Control": "max-age=300"})


def _id() -> Any:
    """A path parameter holding a mission's or a run's id (a new one per route: FastAPI
    names the parameter on the object)."""
    return Path(pattern=r"^[0-9a-f]{1,32}$", description="the id given when it was created")


async def _call(function: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
    """A service call in the thread pool (it may read the database or wait on a lock)."""
    return await run_in_threadpool(function, *args, **kwargs)


def _missions(api: APIRouter, service: Service, max_body: int) -> None:
    upload_body = {"requestBody": {"required": True, "content": {
        "application/xml": {"schema": {"type": "string"}},
        "multipart/form-data": {"schema": {
            "type": "object", "required": ["file"],
            "properties": {"file": {"type": "string", "format": "binary"}}}}}}}

    @api.post("/missions", status_code=201, response_model=MissionSummary, tags=["missions"],
              openapi_extra=upload_body,
              responses={413: {"model": Problem,
                               "description": "larger than --max-body (4 MiB by default)"},
                         415: {"model": Problem, "description": "neither XML nor multipart"}})
    async def upload(request: Request, filename: str | None = Query(
            None, max_length=200, description="the file name diagnostics name (default: "
                                              "the uploaded file's, or mission.xml)"),
                     ) -> MissionSummary:
        """Upload a mission: the XML as the body, or a multipart form with a ``file``.
        Validated as ``tml validate`` does; an invalid mission is answered 422 with its
        ``diagnostics`` (file, line, column, code, message, hint, severity)."""
        kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if kind in ("application/xml", "text/xml"):
            data = await _body(request)
            name = filename or "mission.xml"
        elif kind == "multipart/form-data":
            data, sent_name = await _file(request, max_body)
            name = filename or sent_name or "mission.xml"
        else:
            raise HTTPException(415, "send the mission as application/xml, or as a "
                                     "multipart/form-data field named 'file'")
        return await _call(service.upload, _plain_name(name), data)

    @api.get("/missions", response_model=list[MissionSummary], tags=["missions"])
    def missions() -> list[MissionSummary]:
        """Every stored mission, the oldest first."""
        return service.missions()

    @api.get("/missions/{mission_id}", response_model=MissionDetail, tags=["missions"])
    def mission(mission_id: str = _id()) -> MissionDetail:
        """A mission with its task tree, roles, events and world."""
        return service.mission(mission_id)

    @api.get("/missions/{mission_id}/source", tags=["missions"],
             response_class=Response,
             responses={200: {"content": {"application/xml": {"schema": {"type": "string"}}},
                              "description": "the XML as uploaded"}})
    def source(mission_id: str = _id()) -> Response:
        """The mission's XML as it was uploaded."""
        return Response(service.mission_source(mission_id), media_type="application/xml")

    @api.delete("/missions/{mission_id}", status_code=204, response_class=Response,
                tags=["missions"])
    def delete(mission_id: str = _id()) -> Response:
        """Forget a mission (its runs stay); 409 while a run flies it."""
        service.delete_mission(mission_id)
        return Response(status_code=204)

    @api.post("/missions/{mission_id}/verify", tags=["missions"],
              response_model=dict[str, Any])
    def verify(mission_id: str = _id(),
               request: VerifyRequest | None = None) -> dict[str, object]:
        """The ``tml verify --format json`` report of the mission: every action predicted
        (with its planned ``path``), every violated constraint, ``feasible``."""
        wanted = request or VerifyRequest()
        return report_document(service.verify(mission_id, wanted.profile, wanted.battery))


def _runs(api: APIRouter, service: Service) -> None:
    @api.post("/runs", status_code=201, response_model=RunView, tags=["runs"])
    def start(request: RunRequest) -> RunView:
        """Start a run: verified and checked against the vehicles as ``tml run`` does
        (422 with the report when infeasible, unless ``force``); 409 when a vehicle is
        held by another run."""
        return service.start_run(request.mission, request.vehicles,
                                 safe_state=request.safe_state, profile=request.profile,
                                 force=request.force)

    @api.get("/runs", response_model=list[RunView], tags=["runs"])
    def runs() -> list[RunView]:
        """Every run, the oldest first (without task states)."""
        return service.runs()

    @api.get("/runs/{run_id}", response_model=RunView, tags=["runs"])
    def run(run_id: str = _id()) -> RunView:
        """A run: status, every task's state per vehicle, outcome, exit code."""
        return service.run(run_id)

    @api.post("/runs/{run_id}/abort", response_model=RunView, tags=["runs"])
    def abort(run_id: str = _id()) -> RunView:
        """Abort a run: every vehicle to its safe state; 409 when it has ended."""
        return service.abort(run_id)

    @api.post("/runs/{run_id}/pause", response_model=RunView, tags=["runs"])
    def pause(run_id: str = _id()) -> RunView:
        """Pause a run: its flying vehicles hold where they are, nothing of the mission is
        stepped, and its time limits and elapsed times stop counting; 409 when it has not
        started, is paused already or has ended."""
        return service.control(run_id, "pause")

    @api.post("/runs/{run_id}/resume", response_model=RunView, tags=["runs"])
    def resume(run_id: str = _id()) -> RunView:
        """Resume a paused run: the interrupted actions go on, as after CONTINUE, with the
        time they had left; 409 when it is not paused."""
        return service.control(run_id, "resume")

    @api.post("/runs/{run_id}/continue", response_model=RunView, status_code=201,
              tags=["runs"])
    def continue_run(run_id: str = _id()) -> RunView:
        """Go on with a run the service was flying when it died (status ``interrupted``),
        as ``tml run --resume`` does: a new run on the same vehicles, from where the run's
        log stood -- tasks done stay done, the running one goes on, a plan flown in AUTO is
        followed. 422 when the run was not interrupted, was continued already or has roles;
        409 when a vehicle is held by another run."""
        return service.continue_run(run_id)

    @api.post("/runs/{run_id}/jump", response_model=RunView, tags=["runs"])
    def jump(request: JumpRequest, run_id: str = _id()) -> RunView:
        """Go on from a task, as JUMP_TO_TASK does (what runs is stopped, its vehicle
        holds); 422 with the language's ``code`` when a JUMP_TO_TASK to it would be refused
        (E240 no such task, E244 an ambiguous name, E283 roles or orchestration)."""
        return service.control(run_id, "jump", request.task)

    @api.get("/runs/{run_id}/log", tags=["runs"], response_class=StreamingResponse,
             responses={200: {"content": {"application/x-ndjson": {
                 "schema": {"type": "string"}}}, "description": "one JSON record a line"}})
    def flight_log(run_id: str = _id()) -> StreamingResponse:
        """The run's flight log as JSON lines (``tml run --log``); so far, while it flies."""
        lines = list(service.log(run_id))
        return StreamingResponse(iter(lines), media_type="application/x-ndjson")

    @api.get("/runs/{run_id}/stream", tags=["runs"],
             responses={200: {"content": {"text/event-stream": {"schema": {"type": "string"}}},
                              "description": "record events, then one end event"}})
    async def stream(request: Request, run_id: str = _id(),
                     after: int = Query(0, ge=0, le=LAST_RECORD,
                                        description="send the records numbered above this"),
                     last_event_id: str | None = Header(None, max_length=20),
                     ) -> EventSourceResponse:
        """The run's records as Server-Sent Events, live until the run ends."""
        if last_event_id is not None and last_event_id.isascii() and last_event_id.isdigit():
            # No log has more lines than the query's bound: a larger id asks for nothing.
            after = max(after, min(int(last_event_id), LAST_RECORD))
        await _call(service.run, run_id)  # 404 before the stream starts
        return EventSourceResponse(_events(service, run_id, after, request), ping=15)


def _vehicles(api: APIRouter, service: Service) -> None:
    @api.get("/vehicles", response_model=list[VehicleView], tags=["vehicles"])
    def vehicles() -> list[VehicleView]:
        """Every vehicle with its live telemetry, link state and the run that holds it."""
        return service.vehicles()

    @api.get("/vehicles/{vehicle_id}", response_model=VehicleView, tags=["vehicles"])
    def vehicle(vehicle_id: int = Path(ge=0, le=2**31)) -> VehicleView:
        """One vehicle."""
        return service.vehicle(vehicle_id)

    @api.post("/vehicles/{vehicle_id}/command", response_model=CommandAnswer,
              tags=["vehicles"],
              responses={202: {"model": CommandAnswer,
                               "description": "sent, but not confirmed by the vehicle's "
                                              "telemetry within the command's timeout "
                                              "(outcome not confirmed, what was seen)"}})
    def command(request: CommandRequest, response: Response,
                vehicle_id: int = Path(ge=0, le=2**31)) -> CommandAnswer:
        """Tell a vehicle to return to launch, land, hold or disarm, now; answered 200 once
        the vehicle's telemetry confirms it by its motion (``confirmed``), 202 when it did
        not within the command's timeout (what was seen in ``seen``). 409 with the reason
        when it would be unsafe or cannot be done (a disarm in the air, a ground vehicle
        told to land), when the vehicle refuses it or does not answer. A vehicle no run
        holds is held in a mode that holds by itself (BRAKE, LOITER, HOLD). A vehicle held
        by a run: the operator takes it over through the run: hold pauses it, the others
        end it into that safe state (every vehicle of the run), ``taken``."""
        answer, done = service.command(vehicle_id, request.command)
        if not done:
            response.status_code = 202
        return answer


async def _events(service: Service, run_id: str, after: int,
                  request: Request) -> AsyncIterator[dict[str, Any]]:
    live = service.live(run_id)
    if live is None:
        lines = await _call(lambda: list(service.storage.lines(run_id, after)))
        for seq, line in lines:
            yield {"event": "record", "id": str(seq), "data": line}
        stored = await _call(service.run, run_id)
        yield {"event": "tasks", "data": json.dumps(stored.tasks or {})}
    else:
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[tuple[int, str | None]] = asyncio.Queue()

        def listener(seq: int, line: str | None) -> None:
            loop.call_soon_threadsafe(queue.put_nowait, (seq, line))

        board = live.board
        history, open_ = live.log.listen(after, listener)
        told = board.changes
        try:
            for seq, line in history:
                yield {"event": "record", "id": str(seq), "data": line}
            yield {"event": "tasks", "data": json.dumps(board.snapshot())}
            while open_:
                seq, text = await queue.get()
                if text is None:
                    break
                yield {"event": "record", "id": str(seq), "data": text}
                if board.changes != told:  # the fold moved: the page shows what it says
                    told = board.changes
                    yield {"event": "tasks", "data": json.dumps(board.snapshot())}
        finally:
            live.log.unlisten(listener)
    if not await request.is_disconnected():
        ended = await _call(service.run, run_id)
        yield {"event": "end", "data": json.dumps(ended.model_dump(mode="json", by_alias=True,
                                                                   exclude_none=False))}


# --- requests and errors -----------------------------------------------------------------

async def _body(request: Request) -> bytes:
    data = bytearray()
    async for chunk in request.stream():  # the guard stops a body longer than the limit
        data += chunk
    return bytes(data)


async def _file(request: Request, limit: int) -> tuple[bytes, str]:
    try:
        form = await request.form(max_files=1, max_fields=10, max_part_size=limit)
    except HTTPException:
        raise
    except Exception as error:  # the multipart parser's own errors
        raise HTTPException(400, f"unreadable multipart form: {error}") from None
    try:
        sent = form.get("file")
        if sent is None or isinstance(sent, str):
            raise HTTPException(400, "the form has no file field named 'file'")
        return await sent.read(limit + 1), sent.filename or ""
    finally:
        await form.close()


def _plain_name(name: str) -> str:
    """The last part of a file name, printable: it names the file in diagnostics."""
    last = name.replace("\\", "/").rsplit("/", 1)[-1]
    return "".join(c for c in last if c.isprintable())[:200] or "mission.xml"


def _errors(app: FastAPI) -> None:
    def answer(status: int, message: str, headers: dict[str, str] | None = None,
               more: dict[str, Any] | None = None) -> JSONResponse:
        return JSONResponse({**(more or {}), "error": message}, status_code=status,
                            headers=headers)

    async def refused(_request: Request, error: Exception) -> Response:
        assert isinstance(error, RequestError)
        return answer(error.status, error.message, more=error.detail)

    async def http(request: Request, error: Exception) -> Response:
        assert isinstance(error, HTTPException)
        message = error.detail if isinstance(error.detail, str) else str(error.detail)
        headers = dict(error.headers or {})
        if error.status_code == 404 and message == "Not Found":
            message = "no such route"
        elif error.status_code == 405:
            # Each method of a path is its own route (and a router's routes are behind
            # it): Allow lists the methods some route takes at this path.
            allowed = [method for method in METHODS if any(
                route.matches({**request.scope, "method": method})[0] is Match.FULL
                for route in app.routes)]
            headers["Allow"] = ", ".join(allowed)
            message = f"this route takes {' or '.join(allowed) or 'no method'}"
        return answer(error.status_code, message, headers)

    async def invalid(_request: Request, error: Exception) -> Response:
        assert isinstance(error, RequestValidationError)
        problems = [{"where": ".".join(str(p) for p in e.get("loc", ())),
                     "message": str(e.get("msg", ""))} for e in error.errors()]
        first = problems[0] if problems else {"where": "", "message": "invalid"}
        return answer(422, f"invalid request: {first['where']}: {first['message']}",
                      more={"problems": problems})

    async def storage(_request: Request, error: Exception) -> Response:
        if isinstance(error, OperationalError):
            log.error("the database failed: %s", error)
            return answer(503, "the database is unreachable")
        return answer(503, str(error))

    async def tml_error(_request: Request, error: Exception) -> Response:
        return answer(400, str(error))

    async def unexpected(request: Request, error: Exception) -> Response:
        log.exception("%s %s failed", request.method, request.url.path)
        return answer(500, f"internal error: {type(error).__name__}: {error}")

    handlers: dict[type[Exception], Callable[[Request, Exception], Awaitable[Response]]] = {
        RequestError: refused, HTTPException: http, RequestValidationError: invalid,
        StorageError: storage, OperationalError: storage, TmlError: tml_error,
        Exception: unexpected}
    for kind, handler in handlers.items():
        app.add_exception_handler(kind, handler)
