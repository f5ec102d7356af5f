"""The companion computer attached from outside (sitl.companion_link), fed by hand."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.companion_link import CompanionLink
from tml.geo import to_global
from tml.world import Home, World, WorldObject

HOME = Home(-35.363261, 149.165230, 584.0)
ITEM = WorldObject("item", "A", 8.0, 2.0)


class FakeConnection:
    """What CompanionLink uses of a pymavlink connection: ``mav.send``, ``command_long_send``."""

    def __init__(self) -> None:
        self.mav = self
        self.srcSystem = self.srcComponent = 0
        self.sent: list[Any] = []
        self.commands: list[tuple[int, float, float]] = []

    def send(self, msg: Any) -> None:
        self.sent.append(msg)

    def command_long_send(self, system: int, component: int, command: int, _confirm: int,
                          *params: float) -> None:
        self.commands.append((command, params[0], params[1]))

    def take(self) -> list[Any]:
        sent, self.sent = self.sent, []
        return sent


def from_(msg: Any, system: int = 7, component: int = 1) -> Any:
    msg._header.srcSystem, msg._header.srcComponent = system, component
    return msg


def position(north: float, east: float, up: float, time_ms: int, home: Home = HOME) -> Any:
    lat, lon, _ = to_global(north, east, 0.0, home.latitude, home.longitude, home.altitude)
    return from_(M.MAVLink_global_position_int_message(
        time_ms, round(lat * 1e7), round(lon * 1e7), round((home.altitude + up) * 1000),
        round(up * 1000), 0, 0, 0, 0))


def attitude(yaw: float, time_ms: int) -> Any:
    return from_(M.MAVLink_attitude_message(time_ms, 0.0, 0.0, yaw, 0.0, 0.0, 0.0))


def home_position(home: Home) -> Any:
    return from_(M.MAVLink_home_position_message(
        round(home.latitude * 1e7), round(home.longitude * 1e7), round(home.altitude * 1000),
        0, 0, 0, [1, 0, 0, 0], 0, 0, 0))


def attached(world: World) -> tuple[CompanionLink, FakeConnection]:
    link = CompanionLink("tcp:127.0.0.1:5762", world)
    conn = FakeConnection()
    link.attach(conn, 7, 1)
    return link, conn


def test_attaching_speaks_as_component_191_and_asks_for_the_streams():
    _, conn = attached(World(home=HOME))
    assert (conn.srcSystem, conn.srcComponent) == (7, 191)
    rates = {int(msg_id): 1e6 / interval for command, msg_id, interval in conn.commands
             if command == M.MAV_CMD_SET_MESSAGE_INTERVAL}
    assert rates == {M.MAVLINK_MSG_ID_ATTITUDE: 10.0, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
                     M.MAVLINK_MSG_ID_HOME_POSITION: 0.5}


def test_position_is_taken_in_the_world_frame_and_time_from_the_autopilot():
    link, conn = attached(World(home=HOME, objects=(ITEM,)))
    link.handle(from_(M.MAVLink_param_set_message(7, 191, b"RECOG_ITEMS", 1, 2), 255, 190))
    (echo,) = conn.take()
    assert (echo.get_type(), echo.param_value) == ("PARAM_VALUE", 1.0)
    link.handle(attitude(-math.pi / 2, 61_000))
    assert link.heading == 270.0 and link.position is None  # no position yet
    assert [m.get_type() for m in conn.take()] == ["HEARTBEAT"]
    link.handle(position(8.0, 2.0, 10.0, 61_500))
    north, east, up = link.position
    assert math.dist((north, east), (8.0, 2.0)) < 0.01 and up == 10.0
    sent = conn.take()
    (found,) = [m for m in sent if m.get_type() == "NAMED_VALUE_INT"]
    (where,) = [m for m in sent if m.get_type() == "DEBUG_VECT"]
    assert (found.name, found.value, found.time_boot_ms) == ("ITEM", 1, 61_500)
    assert (where.x, where.y, where.time_usec) == (8.0, 2.0, 61_500_000)
    assert "Detected item 1 A" in [m.text for m in sent if m.get_type() == "STATUSTEXT"]


def test_without_a_world_home_positions_are_from_the_vehicles_home():
    vehicle_home = Home(HOME.latitude + 0.001, HOME.longitude, 590.0)
    link, _ = attached(World(objects=(ITEM,)))
    link.handle(position(5.0, -3.0, 4.0, 1000, vehicle_home))
    assert link.position is None  # no HOME_POSITION yet
    link.handle(home_position(vehicle_home))
    north, east, up = link.position
    assert math.dist((north, east, up), (5.0, -3.0, 4.0)) < 0.01


def test_no_fix_means_no_position_and_other_systems_are_not_listened_to():
    link, conn = attached(World(home=HOME))
    link.handle(position(1.0, 1.0, 1.0, 1000))
    assert link.position is not None
    link.handle(from_(M.MAVLink_global_position_int_message(2000, 0, 0, 0, 0, 0, 0, 0, 0)))
    assert link.position is None
    link.handle(position(3.0, 3.0, 3.0, 3000, HOME))
    link.handle(from_(position(50.0, 50.0, 9.0, 4000), system=8))  # another vehicle
    link.handle(from_(M.MAVLink_param_set_message(8, 191, b"RECOG_ITEMS", 1, 2), 255, 190))
    assert math.dist(link.position, (3.0, 3.0, 3.0)) < 0.01
    assert "PARAM_VALUE" not in [m.get_type() for m in conn.take()]


def test_a_clock_that_goes_back_is_an_autopilot_reboot_skills_off():
    link, conn = attached(World(home=HOME, objects=(ITEM,)))
    link.handle(from_(M.MAVLink_param_set_message(7, 191, b"RECOG_ITEMS", 1, 2), 255, 190))
    link.handle(attitude(0.0, 500_000))
    assert link.companion.params["RECOG_ITEMS"] == 1
    link.handle(attitude(0.0, 2_000))
    assert link.companion.params["RECOG_ITEMS"] == 0
    assert [m.get_type() for m in conn.take()][-1] == "HEARTBEAT"
