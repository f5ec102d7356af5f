"""``tml serve``: the mission interpreter as a service, with an HTTP API and a live page.

Exit codes: 0 stopped (SIGINT, SIGTERM: every flying vehicle sent to its safe state
first), 2 bad arguments (a non-loopback address without a token, an address and port that
cannot be served on -- in use, or not this machine's --, a database that cannot be
opened, ``--cluster`` without PostgreSQL, the ``serve`` extra not installed, a ``--tiles``
file that is not a raster MBTiles file or a ``--tile-url`` that is not a tile URL), 4 the
vehicles cannot be reached.
"""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
import os
import socket
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from tml.commands.signals import on_stop_signals
from tml.commands.vehicles import (
    add_vehicle_arguments,
    component_id,
    positive,
    session_options,
    system_id,
    vehicle_problem,
)
from tml.errors import ExitCode, TmlError

if TYPE_CHECKING:
    import uvicorn

    from tml.serve.hangar import Hangar
    from tml.serve.service import Service
    from tml.serve.storage import Storage
    from tml.serve.tiles import TileSource
    from tml.vehicle import Vehicle

TOKEN_VARIABLE = "TML_SERVE_TOKEN"
MAX_BODY = 4 * 1024 * 1024  # the default of --max-body (tml.serve.guard.MAX_BODY)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``tml serve``."""
    add_vehicle_arguments(parser)
    parser.add_argument("--host", default="127.0.0.1",
                        help="the address to serve on (default 127.0.0.1; any other needs "
                             "a token)")
    parser.add_argument("--port", type=int, default=8080, help="the port (default 8080)")
    parser.add_argument("--data", default="tml-data", metavar="DIR",
                        help="where the SQLite database is kept (default ./tml-data)")
    parser.add_argument("--database", metavar="URL",
                        help="a database URL instead of SQLite in --data, e.g. "
                             "postgresql://user:password@host/tml")
    parser.add_argument("--token", metavar="TOKEN",
                        help=f"every request must carry 'Authorization: Bearer TOKEN' (or "
                             f"--token-file, or ${TOKEN_VARIABLE})")
    parser.add_argument("--token-file", metavar="FILE",
                        help="read the token from the first line of FILE")
    parser.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                        help="a name the service may be called by besides its address and "
                             "localhost (the Host of a request), repeatable")
    parser.add_argument("--max-body", type=int, default=MAX_BODY, metavar="BYTES",
                        help=f"the largest request body taken, a mission upload included "
                             f"(default {MAX_BODY}, 4 MiB)")
    parser.add_argument("--instance", default="local", metavar="NAME",
                        help="this service's name in a database shared by several "
                             "(default local; see docs/serve.md)")
    parser.add_argument("--keep-vehicle-fence", action="store_true",
                        help="leave each vehicle's own fence as it is (by default each run "
                             "uploads its mission's geofence and obstacles as the vehicle's "
                             "fence before take-off; rally points go up either way)")
    tiles = parser.add_argument_group("the page's map (docs/serve.md); without either "
                                      "source, drawn in metres on a grid")
    tiles.add_argument("--tiles", metavar="FILE.mbtiles",
                       help="show the map over the raster tiles of this MBTiles file, served "
                            "by tml itself (works with no network)")
    tiles.add_argument("--tile-url", metavar="TEMPLATE",
                       help="show the map over the tiles of this server, which the browser "
                            "asks itself, e.g. https://tiles.example.org/{z}/{x}/{y}.png")
    tiles.add_argument("--tile-attribution", metavar="TEXT", default="",
                       help="--tile-url: who made the tiles, shown on the map")
    cluster = parser.add_argument_group("cluster (several instances on one PostgreSQL, "
                                        "docs/serve.md)")
    cluster.add_argument("--cluster", action="store_true",
                         help="share the vehicles with the other instances on --database: "
                              "each vehicle is commanded by the one instance that leases it, "
                              "and the runs of an instance that dies are continued by another")
    cluster.add_argument("--lease", type=positive, default=3.0, metavar="S",
                         help="--cluster: seconds a renewal keeps this instance's vehicles "
                              "(default 3, renewed every third of it; keep it well inside "
                              "the vehicles' FS_GCS_TIMEOUT)")
    cluster.add_argument("--source-system", type=system_id, default=255, metavar="N",
                         help="the MAVLink system id this instance sends as (default 255, "
                              "the one ArduPilot's GCS failsafe hears: the instances of a "
                              "cluster share it)")
    cluster.add_argument("--source-component", type=component_id, default=90, metavar="N",
                         help="the MAVLink component id this instance sends as (default "
                              "90; each instance of a cluster may have its own, to be told "
                              "apart in what the vehicles heard)")


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (or localhost)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _token(args: argparse.Namespace) -> str | None:
    """The token: --token, else the first line of --token-file, else the environment."""
    if args.token:
        return str(args.token)
    if args.token_file:
        text = Path(args.token_file).read_text(encoding="utf-8").strip().splitlines()
        if not text or not text[0].strip():
            raise ValueError(f"{args.token_file}: the token file is empty")
        return text[0].strip()
    return os.environ.get(TOKEN_VARIABLE) or None


@contextlib.contextmanager
def _stopped_by_signals(server: uvicorn.Server) -> Iterator[None]:
    """SIGINT and SIGTERM stop the server. uvicorn handles them while it serves, and raises
    the signal again once it has shut down gracefully; this handler then takes it, so that
    the service ends with its own exit code rather than killed by the signal."""
    def stop(_name: str) -> None:
        server.should_exit = True

    with on_stop_signals(stop):
        yield


def run(args: argparse.Namespace) -> ExitCode:
    """Run ``tml serve`` until SIGINT or SIGTERM; return the exit code."""
    try:
        import uvicorn  # noqa: F401  (here: to say what is missing before anything else)

        from tml.serve.api import create_app  # noqa: F401
    except ImportError as error:
        # tml is installed as tml-flight: "tml" on the package index is another project.
        print(f"tml serve: {error.name or error} is missing: install tml with its serve extra "
              "(pip install 'tml-flight[serve]'; in a checkout, pip install '.[serve]')",
              file=sys.stderr)
        return ExitCode.USAGE
    try:
        token = _token(args)
    except (OSError, ValueError) as error:
        print(f"tml serve: {error}", file=sys.stderr)
        return ExitCode.USAGE
    if token is None and not is_loopback(args.host):
        print(f"tml serve: refusing to serve on {args.host} without a token: give --token, "
              f"--token-file or ${TOKEN_VARIABLE}, or serve on 127.0.0.1", file=sys.stderr)
        return ExitCode.USAGE
    if not 0 <= args.port <= 65535:
        print(f"tml serve: --port {args.port}: expected 0 to 65535", file=sys.stderr)
        return ExitCode.USAGE
    problem = vehicle_problem(args)
    if problem is not None:
        print(f"tml serve: {problem}", file=sys.stderr)
        return ExitCode.USAGE
    if args.max_body < 1:
        print(f"tml serve: --max-body {args.max_body}: expected a number of bytes above 0",
              file=sys.stderr)
        return ExitCode.USAGE
    if args.cluster and not (args.database or "").startswith(("postgresql:", "postgres:")):
        print("tml serve: --cluster needs --database postgresql://...: the instances share "
              "their leases there", file=sys.stderr)
        return ExitCode.USAGE
    try:
        tiles = _tiles(args)
    except TmlError as error:
        print(f"tml serve: {error}", file=sys.stderr)
        return ExitCode.USAGE
    try:
        listening = _listen(args.host, args.port)
    except OSError as error:
        print(f"tml serve: cannot serve on {args.host} port {args.port}: "
              f"{error.strerror or error}", file=sys.stderr)
        return ExitCode.USAGE
    with listening:
        return _serve(args, token, listening, tiles)


def _tiles(args: argparse.Namespace) -> TileSource:
    """The map's tile source (--tiles, --tile-url or none), checked; raises TmlError."""
    from tml.serve.tiles import TilesError, TileSource, open_mbtiles, tile_url

    if args.tiles is not None and args.tile_url is not None:
        raise TilesError("--tiles and --tile-url: give one of them (the map shows one "
                         "source of tiles)")
    if args.tile_attribution and args.tile_url is None:
        raise TilesError("--tile-attribution goes with --tile-url (an MBTiles file names "
                         "its own attribution)")
    if args.tiles is not None:
        return open_mbtiles(Path(args.tiles))
    if args.tile_url is not None:
        return tile_url(args.tile_url, args.tile_attribution)
    return TileSource()


def _listen(host: str, port: int) -> socket.socket:
    """A socket bound to ``host`` and ``port`` and listening, before anything is said: a
    port in use is found here, not after the banner."""
    found = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    family, kind, protocol, _name, address = found[0]
    listening = socket.socket(family, kind, protocol)
    try:
        listening.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if family == socket.AF_INET6 and host.strip("[]") == "::":
            listening.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 0)
        listening.bind(address)
        listening.listen(2048)
        listening.set_inheritable(True)
    except OSError:
        listening.close()
        raise
    return listening


def _serve(args: argparse.Namespace, token: str | None, listening: socket.socket,
           tiles: TileSource) -> ExitCode:
    """Open the storage and the vehicles and serve on ``listening`` until stopped."""
    import uvicorn

    from tml.serve.api import create_app
    from tml.serve.service import Service, ServiceOptions
    from tml.serve.storage import Storage, database_url
    from tml.world import World

    try:
        if args.database is None:
            Path(args.data).mkdir(parents=True, exist_ok=True)
        storage = Storage(database_url(args.database, Path(args.data)))
    except (OSError, TmlError) as error:
        print(f"tml serve: {error}", file=sys.stderr)
        return ExitCode.USAGE
    from tml.run.display import output_console
    from tml.run.session import SeveralVehicles, open_session

    hangars: list[Hangar] = []  # the hangar, once the vehicles it holds are open

    def notify() -> None:
        for hangar in hangars:
            hangar.notify()

    # The service's threads fly its runs, on the system's time: the simulator runs free.
    # A cluster's instance opens its vehicles without a word to them: it speaks to each
    # once it leases it (tml.serve.cluster), the FS_GCS_ENABLE check included.
    options = replace(session_options(args, "tml serve"), source_system=args.source_system,
                      source_component=args.source_component, fenced=args.cluster)
    try:
        with open_session(options, World(), output_console(stderr=True),
                          notify=notify) as session, contextlib.ExitStack() as stack:
            if not args.cluster and session.gcs_failsafe() is not None:
                return ExitCode.FAILURE
            vehicles, clock = session.vehicles, session.clock
            hangar = _hangar(args, storage, vehicles, clock)
            hangars.append(hangar)
            service = Service(storage, hangar, ServiceOptions(
                instance=args.instance, link_lost_limit=args.link_lost_limit,
                ready_timeout=args.ready_timeout,
                vehicle_fence=not args.keep_vehicle_fence))
            stack.enter_context(_joined(args, service, hangar))
            port = listening.getsockname()[1]
            where = f"http://{_url_host(args.host)}:{port}/"
            print(f"tml serve: {where} ({len(vehicles)} vehicle(s): "
                  f"{', '.join(str(v.vehicle_id) for v in vehicles)}; {storage.backend} "
                  f"storage{'; token required' if token else ''})", flush=True)
            app = create_app(service, token, bound=args.host, hosts=args.allow_host,
                             max_body=args.max_body, tiles=tiles)
            server = uvicorn.Server(uvicorn.Config(app, log_level="warning"))
            with _stopped_by_signals(server):
                # until SIGINT or SIGTERM; the app's shutdown stops every run
                server.run(sockets=[listening])
            for message in service.said:
                print(f"tml serve: {message}", file=sys.stderr)
            return ExitCode.OK if server.started else ExitCode.USAGE
    except SeveralVehicles as error:
        print(f"tml serve: {error}", file=sys.stderr)
        return ExitCode.USAGE
    except TmlError as error:
        print(f"tml serve: {error}", file=sys.stderr)
        return ExitCode.FAILURE
    except OSError as error:
        print(f"tml serve: cannot open the vehicle link: {error}", file=sys.stderr)
        return ExitCode.FAILURE
    finally:
        storage.close()


def _hangar(args: argparse.Namespace, storage: Storage, vehicles: Sequence[Vehicle],
            clock: Callable[[], float]) -> Hangar:
    """The service's vehicles: its own, or (--cluster) leased from the cluster's tables,
    their links fenced (tml.serve.cluster)."""
    from tml.serve.hangar import Hangar

    if not args.cluster:
        return Hangar(vehicles, clock)
    from tml.serve.cluster import ClusterHangar
    from tml.serve.lease import Leases

    return ClusterHangar(vehicles, clock, Leases(storage.engine, args.instance, args.lease,
                                                 args.source_system),
                         require_gcs_failsafe=args.require_gcs_failsafe)


@contextlib.contextmanager
def _joined(args: argparse.Namespace, service: Service, hangar: Hangar) -> Iterator[None]:
    """The runs this instance was flying when it last stopped: marked interrupted; with
    --cluster, the cluster joined until left, and those runs continued."""
    from tml.serve.cluster import ClusterHangar, clustered

    if not isinstance(hangar, ClusterHangar):
        for run_id in service.start():
            print(f"tml serve: run {run_id} was flying when the service stopped: "
                  "marked interrupted", file=sys.stderr)
        yield
        return
    with clustered(service, hangar) as cluster:
        for old, new in cluster.adopted:
            print(f"tml serve: run {old} was flying when the service stopped: continued "
                  f"as run {new}", file=sys.stderr)
        print(f"tml serve: instance {args.instance} joined the cluster (lease "
              f"{args.lease:g} s, MAVLink system {args.source_system} component "
              f"{args.source_component})", file=sys.stderr)
        yield


def _url_host(host: str) -> str:
    """``host`` as it is written in a URL (an IPv6 address in brackets)."""
    return f"[{host}]" if ":" in host and not host.startswith("[") else host
