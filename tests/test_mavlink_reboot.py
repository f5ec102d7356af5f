"""A reboot told from the autopilot's time_boot_ms stamps (tml.mavlink.reboot)."""

from __future__ import annotations

import pytest

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


# --- a new boot heard late (after an outage), told by the autopilot's word that it boots ---


def old_boot(watch: RebootWatch, until: float, speedup: float = 10.0) -> float:
    """The old boot's stamps at 10 Hz of local time, ``speedup`` times faster, armed, up to
    local time ``until``; returns its last stamp."""
    now = 0.0
    while now <= until + 1e-9:
        watch.heartbeat(True)
        assert not watch.seen(round(now * speedup, 3), now)
        now = round(now + 0.1, 3)
    return round(until * speedup, 3)


@pytest.mark.parametrize("first", [49.0, 52.0, 58.0])
def test_a_new_boot_heard_late_with_its_clock_near_or_past_the_old_ones_is_told(
        first: float) -> None:
    """An ArduCopter SITL at speed-up 10 killed at 52 s of its clock and started again: its
    new boot's clock starts with the kill, its first stamps come once it is asked again
    for its streams (here 4.9 to 5.8 s of local time later), by then near or past the old
    boot's 52 s. Its HEARTBEATs said BOOT as it came back."""
    watch = RebootWatch()
    killed = old_boot(watch, 5.2)
    assert killed == 52.0
    watch.heartbeat(False)  # the new boot's HEARTBEATs: disarmed, BOOT
    assert not watch.boot_sign(5.5)
    now = 5.2 + first / 10
    assert watch.seen(first, now)
    assert watch.reboot == Reboot(52.0, first, armed=True)
    # The new boot followed from there: its rising stamps are nothing more.
    assert not any(feed(watch, [(first + 0.1 * i, now + 0.01 * i) for i in range(1, 300)]))
    assert watch.count == 1


def test_a_boot_said_after_the_first_low_stamp_is_told_at_once() -> None:
    watch = RebootWatch()
    old_boot(watch, 5.2)
    assert not watch.seen(49.0, 10.1)  # 3 s behind: a reordered message, as far as known
    assert watch.boot_sign(10.15)  # ArduPilot's "EKF3 IMU0 initialised"
    assert watch.reboot == Reboot(52.0, 49.0, armed=True)


def test_without_a_word_of_a_boot_a_late_new_boot_near_the_old_clock_is_not_guessed() -> None:
    """The same new boot, its BOOT HEARTBEATs and start-up texts lost: its stamps, soon past
    the old boot's, tell nothing (and a vehicle that runs slow must not be called rebooted)."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    assert not any(feed(watch, [(49.0 + 0.1 * i, 10.1 + 0.01 * i) for i in range(300)]))
    assert watch.reboot is None


def test_a_sitl_that_runs_slow_is_never_a_reboot() -> None:
    """A SITL at speed-up 10 starved of CPU: its clock stands still for 3 s of local time,
    then goes on at a fifth of its speed; its stamps are far behind where its speed said
    they would be, yet none falls behind the highest: nothing is a reboot."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    stamps = [(52.0 + 0.2 * i, 8.2 + 0.1 * i) for i in range(100)]
    assert not any(feed(watch, stamps))
    assert watch.reboot is None


def test_a_boots_own_start_saying_so_while_it_runs_slow_is_no_reboot() -> None:
    """A vehicle's start-up texts come while its first stamps do (ArduCopter's EKF says it
    initialised at about 4.4 s); starved of CPU just then, its clock lags the local time:
    the boot's word is its own, not a new boot's."""
    watch = RebootWatch()
    assert not any(feed(watch, [(3.3 + 0.1 * i, 0.01 * i) for i in range(12)]))
    assert not watch.boot_sign(0.12)  # "EKF3 IMU0 initialised"
    assert not any(feed(watch, [(4.45, 2.5), (4.5, 2.6), (4.4, 2.61), (4.6, 2.7)]))
    assert watch.reboot is None


def test_packets_reordered_or_repeated_after_an_outage_are_never_a_reboot() -> None:
    """After a 2 s outage, messages held on the way arrive out of order and twice, some
    stamped from before the outage; then the vehicle's own go on."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    late = [(49.5, 7.2), (52.0, 7.2), (50.8, 7.21), (51.9, 7.21), (49.5, 7.22), (72.1, 7.3),
            (51.0, 7.3), (72.2, 7.31), (72.2, 7.31), (50.0, 7.6), (72.5, 7.6)]
    assert not any(feed(watch, late))
    assert not any(feed(watch, [(72.5 + 0.5 * i, 7.7 + 0.05 * i) for i in range(40)]))
    assert watch.reboot is None


def test_a_word_of_a_boot_is_forgotten_at_the_old_boots_next_stamp() -> None:
    """A stray BOOT (a forged HEARTBEAT) answered by the autopilot's next stamp: a message
    delayed on the way afterwards is judged as any, no reboot."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    assert not watch.boot_sign(5.25)
    assert not any(feed(watch, [(52.5, 5.25), (51.0, 5.3), (53.0, 5.35), (53.1, 5.4)]))
    assert watch.reboot is None


def test_a_new_boot_saying_so_first_after_an_outage_is_told_before_any_stamp() -> None:
    """ArduCopter SITL started again says BOOT as soon as it is dialled again, and may
    stream nothing for seconds: its word after the outage, said again in its next HEARTBEAT
    (disarmed), is the reboot; its first stamps then start the new boot, no second reboot."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    watch.heartbeat(False)
    assert not watch.boot_sign(10.1)  # one word: it may be forged
    watch.heartbeat(False)
    assert watch.boot_sign(11.1)  # its next HEARTBEAT, still BOOT
    assert watch.reboot == Reboot(52.0, None, armed=True)
    assert str(watch.reboot) == ("rebooted while armed (its clock went from 52.0 s back to "
                                 "a new boot's: it said it was booting)")
    assert not watch.boot_sign(12.1)  # its next BOOT HEARTBEATs
    assert not any(feed(watch, [(49.0 + 0.1 * i, 15.0 + 0.01 * i) for i in range(300)]))
    assert watch.count == 1


def test_a_start_up_text_after_the_word_confirms_it() -> None:
    watch = RebootWatch()
    old_boot(watch, 5.2)
    watch.heartbeat(False)
    assert not watch.boot_sign(10.1)  # BOOT in its HEARTBEAT
    assert watch.boot_sign(10.7)  # "EKF3 IMU0 initialised"
    assert watch.reboot == Reboot(52.0, None, armed=True)


@pytest.mark.parametrize("after", [0.05, 0.6, 3.0])
def test_one_forged_boot_heartbeat_after_an_outage_is_answered_by_the_next_armed_one(
        after: float) -> None:
    """A flying vehicle out of reach for 5 s; heard again, the first HEARTBEAT is a forged
    one saying BOOT. The autopilot's own next HEARTBEAT says armed: no reboot, and a later
    word is a first word again, not a second."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    watch.heartbeat(False)  # the forged one: disarmed, BOOT
    assert not watch.boot_sign(10.1)
    watch.heartbeat(True)  # the autopilot's own, ``after`` s later
    assert not watch.boot_sign(10.1 + after + 1.0)  # a second forged one, later still
    watch.heartbeat(True)
    assert not any(feed(watch, [(102.0 + 0.1 * i, 12.0 + 0.01 * i) for i in range(50)]))
    assert watch.reboot is None and watch.count == 0


def test_words_of_a_boot_sent_in_one_burst_after_an_outage_are_one_word() -> None:
    watch = RebootWatch()
    old_boot(watch, 5.2)
    for i in range(5):  # five forged HEARTBEATs at once
        watch.heartbeat(False)
        assert not watch.boot_sign(10.1 + 0.01 * i)
    watch.heartbeat(True)  # the autopilot's own
    assert watch.reboot is None


def test_a_boot_said_with_no_outage_waits_for_the_stamp_that_shows_it() -> None:
    """The simulator's reboot: its clock drops to zero at once, its first HEARTBEAT says
    BOOT; a stray word of a boot amid the old boot's stamps believes nothing by itself."""
    watch = RebootWatch()
    old_boot(watch, 5.2)
    assert not watch.boot_sign(5.25)
    assert watch.reboot is None
    assert watch.seen(0.0, 5.3)
    assert watch.reboot == Reboot(52.0, 0.0, armed=True)
