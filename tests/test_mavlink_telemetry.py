"""The telemetry tracker folds a vehicle's messages, and only its own, into snapshots."""

from __future__ import annotations

from typing import Any

import pytest

from sitl.model import VehicleModel
from tml.language.kinds import VEHICLE_TYPES
from tml.mavlink.adapter import _messages
from tml.mavlink.codec import mavlink
from tml.mavlink.telemetry import AIRFRAMES, Sighting, TelemetryTracker
from tml.world import DEFAULT_HOME


class Source:
    """Packs messages as a vehicle component would, sequence numbers included."""

    def __init__(self, system: int = 1, component: int = 1) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)

    def __call__(self, name: str, *fields: Any) -> Any:
        msg = getattr(self.mav, f"{name}_encode")(*fields)
        (parsed,) = mavlink.MAVLink(None).parse_buffer(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256
        return parsed


def heartbeat(source: Source, custom_mode: int = 4, armed: bool = True,
              mav_type: int = mavlink.MAV_TYPE_QUADROTOR) -> Any:
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (128 if armed else 0)
    return source("heartbeat", mav_type, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                  base, custom_mode, mavlink.MAV_STATE_ACTIVE)


def test_state_from_the_autopilot_messages() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    for when, msg in enumerate([
        heartbeat(ap),
        ap("global_position_int", 1000, -353632621, 1491652374, 594000, 10000, 150, -50, 20, 0),
        ap("local_position_ned", 1000, 3.0, 4.0, -10.0, 0.0, 0.0, 0.0),
        ap("home_position", -353632621, 1491652374, 584000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0),
        ap("attitude", 1000, 0.1, -0.2, 1.5, 0, 0, 0),
        ap("sys_status", 0, 0, 0, 500, 12600, -1, 87, 0, 0, 0, 0, 0, 0),
        ap("extended_sys_state", 0, 2),
        ap("gps_raw_int", 0, 3, 0, 0, 0, 0, 0, 0, 0, 10),
        ap("ekf_status_report", EKF_USING_GPS, 0, 0, 0, 0, 0),
        ap("mission_current", 3),
        ap("mission_item_reached", 2),
        ap("mission_item_reached", 3),
        ap("statustext", 6, b"Mission: 3 WP"),
    ]):
        assert tracker.apply(msg, float(when))
    t = tracker.snapshot
    assert (t.mode, t.armed, t.vehicle_type, t.last_heartbeat) == ("GUIDED", True, 2, 0.0)
    assert t.position is not None
    assert (t.position.latitude, t.position.relative_altitude) == (-35.3632621, 10.0)
    assert t.velocity == (1.5, -0.5, 0.2) and t.local_position == (3.0, 4.0, -10.0)
    assert t.home is not None and t.home.altitude == 584.0
    assert t.attitude == pytest.approx((0.1, -0.2, 1.5))
    assert (t.battery_voltage, t.battery_remaining) == (12.6, 87)
    assert (t.landed_state, t.gps_fix, t.satellites, t.position_ready) == (2, 3, 10, True)
    assert (t.mission_current, t.items_reached) == (3, (2, 3))
    assert [s.text for s in t.status_texts] == ["Mission: 3 WP"]
    assert t.time == 12.0 and t.heartbeat_age(12.5) == 12.5
    assert (t.boot_time, t.boot_time_received) == (1.0, 4.0)  # the ATTITUDE's time_boot_ms


# EKF_STATUS_REPORT flags ArduCopter SITL sends before and after its EKF uses GPS.
EKF_BEFORE_GPS = 0xA7  # attitude, velocities, vertical position, constant-position mode
EKF_USING_GPS = 0x33F  # ... and horizontal position (relative, absolute, predicted)


def test_position_is_ready_when_the_ekf_uses_gps_not_in_constant_position_mode() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    tracker.apply(ap("ekf_status_report", EKF_BEFORE_GPS, 0, 0, 0, 0, 0), 0.0)
    assert not tracker.snapshot.position_ready
    tracker.apply(ap("ekf_status_report", EKF_USING_GPS | 128, 0, 0, 0, 0, 0), 0.0)
    assert not tracker.snapshot.position_ready  # still holding a constant position
    tracker.apply(ap("ekf_status_report", EKF_USING_GPS, 0, 0, 0, 0, 0), 0.0)
    assert tracker.snapshot.position_ready


def test_prearm_checks_are_read_from_sys_status_and_statustext() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    prearm = mavlink.MAV_SYS_STATUS_PREARM_CHECK
    assert tracker.snapshot.prearm_ok is None and tracker.snapshot.prearm_text == ""
    tracker.apply(ap("sys_status", 0, 0, 0, 500, 12600, -1, 100, 0, 0, 0, 0, 0, 0), 0.0)
    assert tracker.snapshot.prearm_ok is None  # not reported by this autopilot
    tracker.apply(ap("sys_status", prearm, prearm, 0, 500, 12600, -1, 100, 0, 0, 0, 0, 0, 0),
                  1.0)
    tracker.apply(ap("statustext", 2, b"PreArm: Need Position Estimate"), 1.0)
    tracker.apply(ap("statustext", 6, b"EKF3 IMU0 is using GPS"), 2.0)
    assert tracker.snapshot.prearm_ok is False
    assert tracker.snapshot.prearm_text == "PreArm: Need Position Estimate"
    tracker.apply(ap("sys_status", prearm, prearm, prearm, 500, 12600, -1, 100, 0, 0, 0, 0, 0,
                     0), 3.0)
    assert tracker.snapshot.prearm_ok is True


def test_not_ready_before_the_ekf_uses_gps_and_unknown_battery() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    tracker.apply(ap("ekf_status_report", EKF_BEFORE_GPS, 0, 0, 0, 0, 0), 0.0)
    tracker.apply(ap("sys_status", 0, 0, 0, 500, 12600, -1, -1, 0, 0, 0, 0, 0, 0), 0.0)
    assert not tracker.snapshot.position_ready
    assert tracker.snapshot.battery_remaining is None
    assert tracker.snapshot.heartbeat_age(5.0) == float("inf")


def test_other_systems_never_reach_the_state() -> None:
    tracker = TelemetryTracker(1)
    intruder = Source(system=2)
    assert not tracker.apply(heartbeat(intruder, custom_mode=9), 0.0)
    assert tracker.snapshot.mode == "" and tracker.snapshot.received == 0


def test_detections_come_from_the_companion_computer_only() -> None:
    tracker = TelemetryTracker(1)
    companion = Source(component=191)
    gimbal = Source(component=154)
    tracker.apply(companion("named_value_float", 0, b"marker_7", 2.5), 0.0)
    tracker.apply(companion("named_value_int", 0, b"aruco", 12), 0.1)
    tracker.apply(gimbal("named_value_int", 0, b"aruco", 99), 0.2)
    tracker.apply(companion("heartbeat", mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                            mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0), 0.3)
    assert dict(tracker.snapshot.detections) == {"marker_7": 2.5, "aruco": 12}
    assert tracker.snapshot.mode == ""  # a companion's heartbeat is not the vehicle's


def test_loss_is_estimated_from_sequence_gaps() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    for n in range(300):
        msg = ap("attitude", n, 0, 0, 0, 0, 0, 0)
        if n % 4 != 3:  # one in four lost on the way, across the sequence wrap
            tracker.apply(msg, n * 0.01)
    assert tracker.snapshot.received == 225
    assert tracker.snapshot.lost == 74  # the last one lost is not yet visible as a gap
    assert tracker.snapshot.loss == pytest.approx(74 / 299)


def test_messages_that_change_no_state_are_counted_with_their_time() -> None:
    # A mission transfer's requests and ACKs change nothing but the link's counts: they
    # must still count, and be seen with the state that comes between them.
    tracker = TelemetryTracker(1)
    ap = Source()
    tracker.apply(heartbeat(ap), 1.0)
    for n in range(5):
        tracker.apply(ap("mission_request", 250, 190, n, 0), 1.1 + n / 10)
        if n == 2:
            ap.mav.seq += 1  # one lost on the way
    assert (tracker.snapshot.received, tracker.snapshot.lost) == (6, 1)
    assert tracker.snapshot.time == pytest.approx(1.5) and tracker.snapshot.mode == "GUIDED"
    tracker.apply(heartbeat(ap, custom_mode=3), 2.0)
    snapshot = tracker.snapshot
    assert (snapshot.received, snapshot.lost, snapshot.time, snapshot.mode) == (
        7, 1, 2.0, "AUTO")


def test_status_texts_are_bounded() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    for n in range(80):
        tracker.apply(ap("statustext", 6, f"line {n}".encode()), float(n))
    texts = tracker.snapshot.status_texts
    assert len(texts) == 50 and texts[-1].text == "line 79" and texts[0].text == "line 30"
    assert tracker.snapshot.status_text_count == 80
    # The vehicle's state carries the last ten, numbered from the link's first.
    messages = _messages(tracker.snapshot)
    assert [(m.number, m.text) for m in messages] == [(n + 1, f"line {n}")
                                                       for n in range(70, 80)]
    assert {m.severity_name for m in messages} == {"info"}


def test_mode_changes_and_tilts_are_kept_with_their_arrival_times() -> None:
    # What a lost ACK leaves to judge by: a FLIP over in a second shows in one HEARTBEAT
    # and a few ATTITUDEs beyond 57 degrees, and the snapshot after it shows ALT_HOLD again.
    tracker = TelemetryTracker(1)
    ap = Source()
    for when, msg in [(1.0, heartbeat(ap, 4)), (2.0, heartbeat(ap, 4)), (3.0, heartbeat(ap, 2)),
                      (3.5, ap("attitude", 0, 0.3, 0.0, 0.0, 0, 0, 0)),
                      (4.0, heartbeat(ap, 14)),
                      (4.2, ap("attitude", 0, 2.5, 0.0, 0.0, 0, 0, 0)),
                      (4.4, ap("attitude", 0, 0.0, -1.2, 0.0, 0, 0, 0)),
                      (4.6, ap("attitude", 0, 0.1, 0.0, 0.0, 0, 0, 0)),
                      (5.0, heartbeat(ap, 2))]:
        tracker.apply(msg, when)
    t = tracker.snapshot
    assert t.mode_changes == ((1.0, "GUIDED"), (3.0, "ALT_HOLD"), (4.0, "FLIP"),
                              (5.0, "ALT_HOLD"))
    assert t.tilted_at == 4.4
    assert t.mode_shown_since("FLIP", 3.9) and not t.mode_shown_since("FLIP", 4.0)
    assert t.mode_shown_since("ALT_HOLD", 100.0)  # shown now
    assert (t.armed_at, t.disarmed_at) == (5.0, None)
    tracker.apply(heartbeat(ap, 2, armed=False), 6.0)
    assert (tracker.snapshot.armed_at, tracker.snapshot.disarmed_at) == (5.0, 6.0)


def test_mode_changes_are_bounded() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    for n in range(30):
        tracker.apply(heartbeat(ap, 4 if n % 2 else 2), float(n))
    changes = tracker.snapshot.mode_changes
    assert len(changes) == 20 and changes[-1] == (29.0, "GUIDED")


def test_a_vehicle_is_lost_after_the_limit_without_heartbeat_and_found_by_the_next() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    tracker.apply(heartbeat(ap), 10.0)
    assert not tracker.check_link(15.0, lost_after=5.0)  # at the limit: not yet
    tracker.apply(ap("attitude", 0, 0, 0, 0, 0, 0, 0), 15.5)  # other messages do not count
    assert tracker.check_link(15.01, lost_after=5.0) and tracker.snapshot.link_lost
    assert not tracker.check_link(20.0, lost_after=5.0)  # no change: still lost
    tracker.apply(heartbeat(ap), 21.0)
    assert not tracker.snapshot.link_lost and not tracker.check_link(21.0, lost_after=5.0)


def test_sightings_pair_each_named_object_with_the_position_sent_after_it() -> None:
    tracker = TelemetryTracker(1)
    companion = Source(component=191)
    tracker.apply(companion("named_value_int", 500, b"MARKER", 7), 0.0)
    assert tracker.snapshot.sightings[("MARKER", 7)].position is None
    tracker.apply(companion("debug_vect", b"MARKER", 500_000, 3.0, -2.0, 0.5), 0.0)
    tracker.apply(companion("named_value_int", 500, b"MARKER", 8), 0.1)
    tracker.apply(companion("debug_vect", b"MARKER", 499_000, 9.0, 9.0, 9.0), 0.1)  # stale
    tracker.apply(companion("named_value_int", 1000, b"MARKER", 7), 0.5)
    sightings = tracker.snapshot.sightings
    assert sightings[("MARKER", 7)] == Sighting(0.5, (3.0, -2.0, 0.5))  # kept its place
    assert sightings[("MARKER", 8)] == Sighting(0.1, None)
    assert tracker.snapshot.detections["MARKER"] == 7


@pytest.mark.parametrize(("mav_type", "airframe"), [
    (mavlink.MAV_TYPE_QUADROTOR, "quadcopter"),
    (mavlink.MAV_TYPE_HEXAROTOR, "hexacopter"),
    (mavlink.MAV_TYPE_OCTOROTOR, "octocopter"),
    (mavlink.MAV_TYPE_TRICOPTER, "tricopter"),
    (mavlink.MAV_TYPE_COAXIAL, "coaxial"),
    (mavlink.MAV_TYPE_HELICOPTER, "helicopter"),
    (mavlink.MAV_TYPE_FIXED_WING, "fixed-wing"),
    (mavlink.MAV_TYPE_VTOL_DUOROTOR, "vtol"),
    (mavlink.MAV_TYPE_VTOL_QUADROTOR, "vtol"),
    (mavlink.MAV_TYPE_VTOL_TILTROTOR, "vtol"),
    (mavlink.MAV_TYPE_VTOL_RESERVED5, "vtol"),
    (mavlink.MAV_TYPE_VTOL_GYRODYNE, "vtol"),
    (mavlink.MAV_TYPE_GROUND_ROVER, "rover"),
    (mavlink.MAV_TYPE_SURFACE_BOAT, "boat"),
    (mavlink.MAV_TYPE_SUBMARINE, "submarine"),
    (mavlink.MAV_TYPE_AIRSHIP, "airship"),
    (mavlink.MAV_TYPE_GENERIC, ""),
    (mavlink.MAV_TYPE_GCS, ""),
    (mavlink.MAV_TYPE_GIMBAL, ""),
])
def test_the_airframe_is_named_from_the_heartbeat_type(mav_type: int, airframe: str) -> None:
    tracker = TelemetryTracker(1)
    assert tracker.snapshot.airframe == ""  # no HEARTBEAT yet
    tracker.apply(heartbeat(Source(), mav_type=mav_type), 0.0)
    assert tracker.snapshot.airframe == airframe


def test_every_airframe_word_is_a_vehicle_type_and_every_vehicle_type_has_one() -> None:
    assert set(AIRFRAMES.values()) == VEHICLE_TYPES


def test_only_the_autopilots_heartbeat_names_the_airframe() -> None:
    tracker = TelemetryTracker(1)
    gimbal = Source(component=mavlink.MAV_COMP_ID_GIMBAL)
    tracker.apply(heartbeat(gimbal, mav_type=mavlink.MAV_TYPE_GIMBAL), 0.0)
    tracker.apply(heartbeat(gimbal, mav_type=mavlink.MAV_TYPE_HEXAROTOR), 0.1)
    assert tracker.snapshot.airframe == ""
    tracker.apply(heartbeat(Source(), mav_type=mavlink.MAV_TYPE_OCTOROTOR), 0.2)
    tracker.apply(heartbeat(gimbal, mav_type=mavlink.MAV_TYPE_GIMBAL), 0.3)
    assert tracker.snapshot.airframe == "octocopter"


def test_the_simulated_copter_is_a_quadcopter() -> None:
    model = VehicleModel(1, DEFAULT_HOME)
    tracker = TelemetryTracker(1)
    encoders: dict[int, Any] = {}
    decoder = mavlink.MAVLink(None)
    sent = model.step(2.0)
    assert {m.get_srcComponent() for m in sent if m.get_type() == "HEARTBEAT"} == {1, 191}
    for msg in sent:
        component = msg.get_srcComponent()
        encoder = encoders.setdefault(component, mavlink.MAVLink(None, 1, component))
        (received,) = decoder.parse_buffer(msg.pack(encoder))
        encoder.seq = (encoder.seq + 1) % 256
        tracker.apply(received, model.time)
    t = tracker.snapshot
    assert (t.vehicle_type, t.airframe) == (mavlink.MAV_TYPE_QUADROTOR, "quadcopter")


def test_absurd_values_are_ignored_and_counted_with_what_was_wrong() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    tracker.apply(heartbeat(ap), 0.0)
    tracker.apply(ap("sys_status", 0, 0, 0, 500, 12600, -1, 87, 0, 0, 0, 0, 0, 0), 0.1)
    tracker.apply(ap("attitude", 1000, 0.1, -0.2, 1.5, 0, 0, 0), 0.2)
    tracker.apply(ap("gps_raw_int", 0, 3, 0, 0, 0, 0, 0, 0, 0, 10), 0.3)
    tracker.apply(ap("global_position_int", 1000, -353632621, 1491652374, 594000, 10000,
                     150, -50, 20, 0), 0.4)
    absurd = [
        (ap("sys_status", 0, 0, 0, 500, 12600, -1, 127, 0, 0, 0, 0, 0, 0),
         "SYS_STATUS.battery_remaining = 127"),
        (ap("attitude", 1000, 0.1, -0.2, float("nan"), 0, 0, 0), "ATTITUDE.yaw = nan"),
        (ap("gps_raw_int", 0, 255, 0, 0, 0, 0, 0, 0, 0, 10), "GPS_RAW_INT.fix_type = 255"),
        (ap("global_position_int", 1000, -353632621, 1491652374, 2_000_000_000, 1_990_000_000,
            150, -50, 20, 0), "GLOBAL_POSITION_INT.alt = 2e+06"),
        (ap("global_position_int", 1000, 1_900_000_000, 1491652374, 594000, 10000,
            150, -50, 20, 0), "GLOBAL_POSITION_INT.lat = 190"),
    ]
    for number, (msg, said) in enumerate(absurd, start=1):
        tracker.apply(msg, 1.0 + number)
        snapshot = tracker.snapshot
        assert snapshot.rejected == number
        assert snapshot.rejected_last.startswith(said), snapshot.rejected_last
    snapshot = tracker.snapshot
    assert snapshot.battery_remaining == 87 and snapshot.attitude == (
        pytest.approx(0.1), pytest.approx(-0.2), pytest.approx(1.5))
    assert snapshot.gps_fix == 3 and snapshot.position is not None
    assert snapshot.position.altitude == 594 and snapshot.position.latitude < 0


def test_the_revision_counts_only_messages_that_change_what_the_vehicle_shows() -> None:
    tracker = TelemetryTracker(1)
    ap = Source()
    tracker.apply(heartbeat(ap), 0.0)
    first = tracker.snapshot.revision
    tracker.apply(heartbeat(ap), 1.0)  # the same mode, armed: only its time and count differ
    assert tracker.snapshot.revision == first
    assert (tracker.snapshot.received, tracker.snapshot.last_heartbeat) == (2, 1.0)
    battery = [0, 0, 0, 500, 12600, -1, 87, 0, 0, 0, 0, 0, 0]
    tracker.apply(ap("sys_status", *battery), 1.5)
    assert tracker.snapshot.revision == first + 1
    tracker.apply(ap("sys_status", *battery), 2.0)
    assert tracker.snapshot.revision == first + 1
    battery[6] = 20  # percent left
    tracker.apply(ap("sys_status", *battery), 2.5)
    assert (tracker.snapshot.revision, tracker.snapshot.battery_remaining) == (first + 2, 20)
    assert tracker.check_link(9.0, 5.0) and tracker.snapshot.revision == first + 3  # lost
    tracker.apply(heartbeat(ap), 9.5)  # back
    assert not tracker.snapshot.link_lost and tracker.snapshot.revision == first + 4
