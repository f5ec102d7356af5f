"""When an operator's command is done: its mode is not enough, the motion must show it."""

from __future__ import annotations

from dataclasses import replace

from tml.engine.confirm import HOLD_TIME, Confirmation
from tml.vehicle import VehicleState

FLYING = VehicleState(1, 0.0, armed=True, landed=False, mode="GUIDED",
                      position=(100.0, 0.0, 10.0), ground_speed=6.0, vehicle_type="quadcopter")


def feed(confirmation: Confirmation, states: list[tuple[float, VehicleState]]) -> list[bool]:
    return [confirmation.see(state, at) for at, state in states]


def test_a_hold_is_done_after_its_stop_lasted_the_hold_time() -> None:
    stopped = replace(FLYING, mode="BRAKE", ground_speed=0.1)
    seen = feed(Confirmation("hold"), [(0.0, replace(FLYING, mode="BRAKE")), (1.0, stopped),
                                       (1.0 + HOLD_TIME - 0.1, stopped),
                                       (1.0 + HOLD_TIME, stopped)])
    assert seen == [False, False, False, True]


def test_a_hold_in_guided_that_flies_on_is_never_done() -> None:
    # The defect: GUIDED shown, the vehicle slowed, then the run's next target took it on.
    confirmation = Confirmation("hold")
    states = [(t, replace(FLYING, ground_speed=speed))
              for t, speed in [(0.0, 6.0), (1.0, 4.5), (2.0, 4.5), (3.0, 6.0), (9.0, 6.0)]]
    assert not any(feed(confirmation, states))
    assert "mode GUIDED" in confirmation.seen() and "ground speed 6.0 m/s" in confirmation.seen()


def test_a_stop_broken_starts_the_count_again() -> None:
    stopped = replace(FLYING, mode="BRAKE", ground_speed=0.0)
    seen = feed(Confirmation("hold"), [(0.0, stopped), (2.0, stopped),
                                       (2.5, replace(stopped, ground_speed=1.0)),
                                       (3.5, stopped), (6.4, stopped), (6.5, stopped)])
    assert seen == [False, False, False, False, False, True]


def test_a_sink_is_no_hold() -> None:
    sinking = replace(FLYING, mode="LOITER", ground_speed=0.0, climb=-1.0)
    assert not any(feed(Confirmation("hold"), [(t, sinking) for t in range(10)]))


def test_a_fixed_wing_holds_by_circling_in_its_mode() -> None:
    circling = replace(FLYING, mode="LOITER", ground_speed=20.0, vehicle_type="fixed-wing")
    assert feed(Confirmation("hold"), [(0.0, circling), (HOLD_TIME, circling)]) == [False, True]


def test_rtl_is_done_once_the_vehicle_comes_nearer_home() -> None:
    returning = replace(FLYING, mode="RTL")
    seen = feed(Confirmation("rtl"), [(0.0, returning),
                                      (1.0, replace(returning, position=(99.5, 0.0, 12.0))),
                                      (2.0, replace(returning, position=(98.9, 0.0, 15.0)))])
    assert seen == [False, False, True]


def test_rtl_shown_by_its_mode_alone_is_not_done() -> None:
    confirmation = Confirmation("rtl")
    assert not any(feed(confirmation, [(t, replace(FLYING, mode="RTL")) for t in range(5)]))
    assert "100 m from home" in confirmation.seen()


def test_rtl_of_a_vehicle_already_landed_elsewhere_is_not_done() -> None:
    # The defect: a vehicle that had landed 100 m from home (its mission's LAND) was told
    # "rtl done" since it was on the ground, disarmed; it never went home.
    landed = replace(FLYING, mode="LAND", armed=False, landed=True, ground_speed=0.0,
                     position=(100.0, 0.0, 0.0))
    confirmation = Confirmation("rtl")
    assert not any(feed(confirmation, [(t, landed) for t in range(5)]))
    assert "mode LAND, disarmed, on the ground" in confirmation.seen()
    assert "100 m from home" in confirmation.seen()


def test_rtl_is_done_when_its_landing_ends_disarmed_or_at_home() -> None:
    returning = replace(FLYING, mode="RTL", position=(0.5, 0.0, 3.0))
    down = replace(returning, armed=False, landed=True, position=(0.5, 0.0, 0.0))
    assert feed(Confirmation("rtl"), [(0.0, returning), (1.0, down)]) == [True, True]
    assert feed(Confirmation("rtl"), [(0.0, replace(down, mode="LAND"))]) == [True]
    far_down = replace(down, position=(40.0, 0.0, 0.0))  # landed at a rally point
    assert feed(Confirmation("rtl"), [(0.0, replace(returning, position=(41.0, 0.0, 2.0))),
                                      (1.0, far_down)]) == [False, True]


def test_a_landing_is_done_once_the_vehicle_descends() -> None:
    landing = replace(FLYING, mode="LAND", ground_speed=0.0)
    seen = feed(Confirmation("land"), [(0.0, landing),
                                       (1.0, replace(landing, position=(100.0, 0.0, 9.6))),
                                       (2.0, replace(landing, position=(100.0, 0.0, 9.4)))])
    assert seen == [False, False, True]


def test_nothing_is_done_from_a_picture_older_than_the_command() -> None:
    old = replace(FLYING, mode="BRAKE", ground_speed=0.0, heard=1.0, asked=2.0)
    assert not any(feed(Confirmation("hold"), [(t, old) for t in range(10)]))
    assert Confirmation("hold").seen() == "no telemetry after the command"


def test_disarm_is_done_when_disarmed_on_the_ground() -> None:
    ground = replace(FLYING, landed=True, ground_speed=0.0, position=(0.0, 0.0, 0.0))
    assert feed(Confirmation("disarm"), [(0.0, ground), (1.0, replace(ground, armed=False))]) \
        == [False, True]


def test_a_stop_in_guided_whose_reported_target_is_elsewhere_is_no_hold() -> None:
    from tml.mavlink.targets import GuidedTarget

    slow = replace(FLYING, ground_speed=0.2)  # slowed, but told to fly on
    away, stop = GuidedTarget(1.0, distance=152.0), GuidedTarget(2.0, speed=0.0)
    confirmation = Confirmation("hold")
    assert not any(confirmation.see(slow, t, away) for t in range(10))
    assert confirmation.seen().endswith("GUIDED target 152 m away")
    assert [confirmation.see(slow, t, stop) for t in (10.0, 13.0)] == [False, True]
    assert confirmation.seen().endswith("GUIDED target velocity 0.0 m/s")
