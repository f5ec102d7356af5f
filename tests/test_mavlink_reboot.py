"""A reboot told from the autopilot's time_boot_ms stamps (tml.mavlink.reboot)."""

from __future__ import annotations

from tml.mavlink.reboot import AGREE, Reboot, RebootWatch


def feed(watch: RebootWatch, stamps: list[tuple[float, float]]) -> list[bool]:
    return [watch.seen(stamp, now) for stamp, now in stamps]


def test_a_clock_that_goes_back_and_stays_back_is_a_reboot_believed_once() -> None:
    watch = RebootWatch()
    watch.heartbeat(True)
    assert feed(watch, [(810.0, 0.0), (812.3, 1.0)]) == [False, False]
    watch.heartbeat(True)
    assert feed(watch, [(0.4, 5.0), (0.6, 5.2), (1.3, 5.0 + AGREE), (1.5, 7.0)]) == [
        False, False, True, False]
    assert watch.reboot == Reboot(812.3, 0.4, armed=True)
    assert str(watch.reboot) == \
        "rebooted while armed (its clock went from 812.3 s back to 0.4 s)"


def test_one_stray_or_forged_low_stamp_is_answered_by_the_next_genuine_one() -> None:
    watch = RebootWatch()
    # A forged message stamped 0.1 s, then the autopilot's own: nothing is believed, even
    # when later low stamps come (each answered by a genuine one).
    stamps = [(500.0, 0.0), (0.1, 0.5), (500.6, 0.6), (0.2, 1.0), (501.0, 1.0 + AGREE + 0.1),
              (0.3, 3.0), (501.5, 3.2)]
    assert not any(feed(watch, stamps))
    assert watch.reboot is None


def test_a_message_delayed_on_the_way_is_no_reboot() -> None:
    watch = RebootWatch()
    assert not any(feed(watch, [(100.0, 0.0), (100.9, 0.9), (100.2, 2.0), (100.4, 3.5)]))


def test_a_vehicle_disarmed_when_it_rebooted_is_said_so() -> None:
    watch = RebootWatch()
    watch.heartbeat(True)  # armed long before: flew, landed, disarmed
    feed(watch, [(10.0, 0.0), (60.0, 50.0)])
    watch.heartbeat(False)
    assert feed(watch, [(0.2, 51.0), (1.2, 52.0)]) == [False, True]
    assert watch.reboot is not None and not watch.reboot.armed
    assert str(watch.reboot).startswith("rebooted disarmed (its clock went from 60.0 s")


def test_the_new_boots_disarmed_heartbeats_do_not_hide_an_armed_reboot() -> None:
    watch = RebootWatch()
    feed(watch, [(30.0, 0.0)])
    watch.heartbeat(True)
    feed(watch, [(31.0, 1.0)])
    watch.heartbeat(False)  # the new boot's first HEARTBEAT comes before any stamp
    feed(watch, [(0.5, 3.0), (1.5, 4.0)])
    assert watch.reboot is not None and watch.reboot.armed


def test_after_a_reboot_the_new_boot_is_followed_and_a_second_reboot_told() -> None:
    watch = RebootWatch()
    assert feed(watch, [(300.0, 0.0), (0.5, 1.0), (1.5, 2.0)]) == [False, False, True]
    assert watch.count == 1
    # The new boot's stamps go on rising: nothing more; then it reboots again.
    assert not any(feed(watch, [(2.5, 3.0), (40.0, 40.0)]))
    assert feed(watch, [(0.3, 41.0), (1.3, 42.0)]) == [False, True]
    assert watch.count == 2 and watch.reboot == Reboot(40.0, 0.3, armed=False)
