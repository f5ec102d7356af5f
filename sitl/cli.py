"""``python -m sitl``: run simulated vehicles until interrupted.

Prints one line per vehicle saying where it listens, then serves until SIGINT or SIGTERM
and exits 0. Bad arguments or an unusable world file give one clear line on stderr and
exit status 2; a port that cannot be opened gives one line naming the vehicle and the port
(and, for one in use, ``--tcp-base-port``) and exit status 1.
"""

from __future__ import annotations

import argparse
import errno
import math
import signal
import sys
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NoReturn

from sitl import MAX_VEHICLES
from sitl.faults import Faults
from tml.errors import TmlError
from tml.world import Home, World

if TYPE_CHECKING:
    from sitl.server import PortUnavailable


def _home(text: str) -> Home:
    parts = text.split(",")
    try:
        values = [float(part) for part in parts]
    except ValueError:
        values = []
    if len(values) not in (3, 4):
        raise argparse.ArgumentTypeError(f"expected lat,lon,alt[,heading], got {text!r}")
    lat, lon, alt = values[:3]
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise argparse.ArgumentTypeError(f"latitude/longitude out of range in {text!r}")
    return Home(lat, lon, alt, values[3] if len(values) == 4 else 0.0)


def _probability(text: str) -> float:
    value = non_negative(text)
    if value > 1:
        raise argparse.ArgumentTypeError(f"expected a probability between 0 and 1, got {text}")
    return value


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def non_negative(text: str) -> float:
    """A finite number of at least 0 (an argparse type, shared with ``tml run``): nan and
    inf are refused, as no clock or limit can run with them."""
    value = _number(text)
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number of at least 0, got {text}")
    return value


def positive(text: str) -> float:
    """A finite number greater than 0 (an argparse type, shared with ``tml run``)."""
    value = _number(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a finite number greater than 0, got {text}")
    return value


def count(text: str) -> int:
    """A whole number of at least 1 (an argparse type, shared with ``tml run``)."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}")
    return int(text)


def vehicle_count(text: str) -> int:
    """A number of simulated vehicles: 1 to MAX_VEHICLES (system ids 1..N, one byte each)."""
    number = count(text)
    if number > MAX_VEHICLES:
        raise argparse.ArgumentTypeError(
            f"at most {MAX_VEHICLES} vehicles (a MAVLink system id is one byte), got {text}")
    return number


def _port(text: str) -> int:
    """A TCP port number, 0 to 65535 (0: any free port)."""
    if not text.isdigit() or int(text) > 65535:
        raise argparse.ArgumentTypeError(f"expected a port number from 0 to 65535, got {text!r}")
    return int(text)


def _window(text: str) -> tuple[float, float]:
    start, _, end = text.partition(":")
    try:
        window = float(start), float(end)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected START:END in seconds, got {text!r}") from None
    if window[1] < window[0]:
        raise argparse.ArgumentTypeError(f"outage {text!r} ends before it starts")
    return window


def _rejection(text: str) -> tuple[int, int]:
    command, _, result = text.partition(":")
    if not command.isdigit() or (result and not result.isdigit()):
        raise argparse.ArgumentTypeError(f"expected CMD_ID[:RESULT], got {text!r}")
    return int(command), int(result or 4)


def param_setting(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` -> (NAME, value) for a vehicle parameter the simulator has, on any
    of its frames (an argparse type, shared with ``tml run --sim-param``)."""
    from sitl.params import AUTOPILOT_DEFAULTS, PLANE_DEFAULTS, ROVER_DEFAULTS

    name, _, value = text.partition("=")
    name = name.strip().upper()
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER, got {text!r}") from None
    tables = (AUTOPILOT_DEFAULTS, PLANE_DEFAULTS, ROVER_DEFAULTS)
    if name not in {known for table in tables for known, _, _ in table}:
        raise argparse.ArgumentTypeError(f"unknown simulator parameter {name!r} "
                                         "(sitl/params.py lists them)")
    return name, number


def battery_start(text: str) -> tuple[str, float]:
    """``PERCENT`` -> the setting of the battery's charge at boot (an argparse type, shared
    with ``tml run --sim-battery``): a finite number from 0 to 100."""
    value = _number(text)
    if not math.isfinite(value) or not 0 <= value <= 100:
        raise argparse.ArgumentTypeError(f"expected a percentage from 0 to 100, got {text}")
    return "SIM_BATT_START", value


class FastBoot(argparse.Action):
    """A flag that adds the settings of a fast start-up (:data:`sitl.params.FAST_BOOT`) to
    the parameter settings (shared with ``tml run --sim-fast-boot``)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        from sitl.params import FAST_BOOT

        # A new list: the default one is shared by every parse.
        setattr(namespace, self.dest, [*(getattr(namespace, self.dest, None) or []),
                                       *FAST_BOOT])


def _frames(text: str) -> list[str]:
    from sitl.frames import parse_frames

    try:
        return parse_frames(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _udp(text: str) -> str:
    """An output address the simulator can send to: well formed, and its host known."""
    import socket

    from sitl.server import parse_udp_address

    try:
        host, port = parse_udp_address(text)
        socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    except OSError as error:
        raise argparse.ArgumentTypeError(f"{text}: cannot send there: {error}") from None
    return text


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage error is one line: what is wrong, and where the
    help is (not argparse's synopsis of every option first)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(prog: str = "python -m sitl") -> argparse.ArgumentParser:
    """The argument parser of ``python -m sitl`` (``tml sim`` gives its own name).

    Each option's help says its default in its own words (argparse's formatter would add
    "(default: None)" to the options that have none)."""
    parser = _Parser(
        prog=prog,
        description="Simulated ArduPilot vehicles (Copter, Plane, Rover) speaking MAVLink 2 "
                    "over TCP and UDP, until SIGINT or SIGTERM. Exit 0 when stopped, 1 when "
                    "a vehicle's port cannot be opened (one in use: choose others with "
                    "--tcp-base-port), 2 on bad arguments or a file it cannot use (--world, "
                    "--signing-key-file, --heard).",
    )
    parser.add_argument("--vehicles", type=vehicle_count, default=1, metavar="N",
                        help="number of vehicles, system ids 1..N (at most 255; default 1)")
    parser.add_argument("--frame", type=_frames, default=["copter"], metavar="FRAME[,FRAME...]",
                        help="copter (default), plane or rover; a list gives vehicle 1, 2 ... "
                             "theirs, the last repeating (e.g. copter,rover)")
    parser.add_argument("--home", type=_home, metavar="LAT,LON,ALT[,HEADING]",
                        help="where vehicle 1 boots (default: the world's home, else "
                             "ArduPilot SITL's CMAC); vehicle i boots 5 m east of vehicle i-1")
    parser.add_argument("--speedup", type=positive, default=1.0, metavar="K",
                        help="vehicle time runs K times faster than real time (default 1)")
    parser.add_argument("--world", metavar="FILE",
                        help="world file (obstacles, geofence, objects, home), or a mission "
                             "file, whose <environment> is taken (default: an empty world)")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="seed of every random choice (default 0)")
    parser.add_argument("--tcp-base-port", type=_port, default=5760, metavar="P",
                        help="TCP port of vehicle 1; vehicle i listens on P + 10*(i-1), as "
                             "ArduPilot SITL's instances do (default 5760); 0 = any free port")
    parser.add_argument("--bind", default="127.0.0.1", metavar="HOST",
                        help="the address to listen on (default 127.0.0.1)")
    parser.add_argument("--out", action="append", type=_udp, default=[], metavar="ADDRESS",
                        help="also stream to a ground station at this MAVLink address, "
                             "udp:HOST:PORT; repeatable")
    parser.add_argument("--param", type=param_setting, action="append", default=[],
                        metavar="NAME=VALUE",
                        help="set a parameter of every vehicle (e.g. SIM_COMPANION=0: no "
                             "embedded companion computer); repeatable")
    parser.add_argument("--battery", type=battery_start, action="append", dest="param",
                        metavar="PERCENT",
                        help="the charge of every vehicle's battery at boot, 0 to 100 "
                             "(default 100; the parameter SIM_BATT_START)")
    parser.add_argument("--fast-boot", action=FastBoot, dest="param",
                        help="GPS lock after 1 s and the EKF on GPS after 2 s of vehicle time, "
                             "instead of ArduCopter's 10 and 41 s (SIM_GPS_LOCKTIME=1 "
                             "SIM_EKF_GPS_TIME=2): armable at once")
    parser.add_argument("--signing-key-file", metavar="FILE",
                        help="MAVLink 2 signing: sign what the vehicles send and refuse what "
                             "is unsigned or wrongly signed; the file holds 64 hex digits or "
                             "a passphrase (else the key of TML_SIGNING_KEY, if set; without "
                             "either, nothing is signed)")
    parser.add_argument("--heard", metavar="FILE",
                        help="write every message a vehicle receives to FILE, one JSON line "
                             "each: vehicle, vehicle and wall time, sender system and "
                             "component, type (who commanded which vehicle when)")
    faults = parser.add_argument_group("faults (none by default)")
    faults.add_argument("--loss-in", type=_probability, default=0.0, metavar="P",
                        help="probability a message to the vehicle is lost")
    faults.add_argument("--loss-out", type=_probability, default=0.0, metavar="P",
                        help="probability a message from the vehicle is lost")
    faults.add_argument("--latency", type=non_negative, default=0.0, metavar="S",
                        help="seconds of delay")
    faults.add_argument("--jitter", type=non_negative, default=0.0, metavar="S",
                        help="extra random delay, up to S seconds")
    faults.add_argument("--duplicate", type=_probability, default=0.0, metavar="P",
                        help="probability a message is delivered twice")
    faults.add_argument("--reorder", type=_probability, default=0.0, metavar="P",
                        help="probability a message is overtaken by later ones")
    faults.add_argument("--outage", type=_window, action="append", default=[],
                        metavar="START:END", help="no link between these vehicle times (s); "
                                                  "repeatable")
    faults.add_argument("--reject", type=_rejection, action="append", default=[],
                        metavar="CMD[:RESULT]",
                        help="answer MAV_CMD CMD with MAV_RESULT RESULT (default 4, FAILED); "
                             "repeatable")
    faults.add_argument("--gps-loss-at", type=non_negative, metavar="T",
                        help="vehicle time (s) the GPS loses its fix")
    faults.add_argument("--battery-failure-at", type=non_negative, metavar="T",
                        help="vehicle time (s) the battery collapses")
    faults.add_argument("--reboot-at", type=non_negative, metavar="T",
                        help="vehicle time (s) the autopilot reboots")
    return parser


def _unavailable(error: PortUnavailable) -> str:
    """What a port that cannot be opened means, and the option that changes it."""
    if error.errno == errno.EADDRINUSE:
        return (f"vehicle {error.system_id} cannot listen on TCP port {error.port} of "
                f"{error.host}: it is in use (another simulator or autopilot?); choose other "
                "ports with --tcp-base-port P (vehicle i listens on P + 10*(i-1); 0 takes "
                "free ones)")
    where = f"port {error.port} of {error.host}" if error.port else error.host
    if error.errno == errno.EACCES:
        return (f"vehicle {error.system_id} cannot listen on {where}: {error.strerror} "
                "(choose other ports with --tcp-base-port P)")
    return (f"vehicle {error.system_id} cannot listen on {where}: {error.strerror} (--bind "
            f"{error.host}: is it an address of this machine?)")


def _load_world(path: str) -> World:
    """A world file's world, or a mission file's ``<environment>``."""
    from tml.language.build import load_world
    from tml.language.validation import load_mission
    from tml.language.xml import root_name

    if root_name(path) == "mission":
        return load_mission(path).world or World()
    return load_world(path)


def main(argv: Sequence[str] | None = None, prog: str = "python -m sitl") -> int:
    """Run the simulator; returns the exit status."""
    parser = build_parser(prog)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)
    last = args.tcp_base_port + 10 * (args.vehicles - 1)
    if args.tcp_base_port and last > 65535:
        print(f"{prog}: error: --tcp-base-port {args.tcp_base_port} with {args.vehicles} "
              f"vehicles puts vehicle {args.vehicles} on port {last}, past 65535 (see {prog} "
              "--help)", file=sys.stderr)
        return 2
    try:
        world = _load_world(args.world) if args.world else None
    except TmlError as error:
        print(f"{prog}: --world {args.world}: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"{prog}: --world {args.world}: {error.strerror or error}", file=sys.stderr)
        return 2
    from tml.signing import signing_key

    try:
        key = signing_key(args.signing_key_file)
    except OSError as error:
        print(f"{prog}: --signing-key-file {args.signing_key_file}: "
              f"{error.strerror or error}", file=sys.stderr)
        return 2
    except TmlError as error:
        print(f"{prog}: signing key: {error}", file=sys.stderr)
        return 2
    faults = Faults(
        seed=args.seed, loss_in=args.loss_in, loss_out=args.loss_out, latency=args.latency,
        jitter=args.jitter, duplicate=args.duplicate, reorder=args.reorder,
        outages=tuple(args.outage), reject_commands=dict(args.reject),
        gps_loss_at=args.gps_loss_at, battery_failure_at=args.battery_failure_at,
        reboot_at=args.reboot_at,
    )
    from sitl.frames import frame_of
    from sitl.server import PortUnavailable, Simulator

    try:
        heard = open(args.heard, "a", encoding="utf-8") if args.heard else None  # noqa: SIM115
    except OSError as error:
        print(f"{prog}: --heard {args.heard}: {error.strerror or error}", file=sys.stderr)
        return 2
    simulator = Simulator(
        vehicles=args.vehicles, home=args.home, speedup=args.speedup, seed=args.seed,
        world=world, faults=faults, tcp_base_port=args.tcp_base_port, udp_out=args.out,
        bind=args.bind, params=dict(args.param), frames=args.frame, signing_key=key,
        heard=heard,
    )
    try:
        simulator.start()
    except PortUnavailable as error:
        print(f"{prog}: {_unavailable(error)}", file=sys.stderr)
        return 1
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set())
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        tcp = simulator.tcp_ports
        udp = simulator.udp_ports
        for index, model in enumerate(simulator.vehicles):
            where = [f"tcp:{args.bind}:{tcp[index]}"] if tcp else []
            if udp:
                where += [f"udp out {a} from port {udp[index]}" for a in args.out]
            home = model.home
            print(f"vehicle {model.system_id}: {', '.join(where) or 'no link'} "
                  f"({frame_of(args.frame, index)}; "
                  f"home {home.latitude:.7f},{home.longitude:.7f},{home.altitude:.1f}; "
                  f"speedup {args.speedup:g})", flush=True)
        while not stop.wait(0.2):
            pass
    finally:
        simulator.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if heard is not None:
            heard.close()
    return 0
