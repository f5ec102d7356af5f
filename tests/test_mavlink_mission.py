"""The mission-transfer state machine against a fake vehicle over a deterministic lossy link.

Time is simulated: the link delivers messages after a fixed latency and drops each one with
a seeded probability, so the tests neither sleep nor touch sockets.
"""

from __future__ import annotations

import heapq
import json
import math
import random
from dataclasses import replace
from pathlib import Path

import pytest

from tml.errors import MissionTransferError
from tml.mavlink.mission import (
    Clear,
    Download,
    ItemDifference,
    MissionAck,
    MissionClearAll,
    MissionCount,
    MissionItem,
    MissionMessage,
    MissionRequest,
    MissionRequestList,
    MissionResult,
    MissionType,
    Progress,
    Transfer,
    Unstorable,
    Upload,
    ardupilot_form,
    exact_form,
    read_back_differences,
    result_name,
    same_items,
    with_home_placeholder,
)

ACCEPTED = MissionResult.MAV_MISSION_ACCEPTED


class MissionResponder:
    """The vehicle's side of the mission protocol, as ArduPilot's MissionItemProtocol plays it.

    It asks for items with the legacy MISSION_REQUEST, asks again every ``rerequest``
    seconds while an upload is open, and cancels it after ``give_up`` seconds without a new
    item. It accepts the item it expects whether asked for or not, answers any other item
    with MISSION_ACK INVALID_SEQUENCE, and ignores items once the upload is over (so a lost
    final ACK is never repeated). With ``home_slot`` it overwrites item 0 of a mission with
    its own home.
    """

    def __init__(self, rerequest: float = 1.0, give_up: float = 8.0, home_slot: bool = False,
                 refuse: int | None = None) -> None:
        self.lists: dict[int, list[MissionItem]] = {}
        self.rerequest = rerequest
        self.give_up = give_up
        self.home_slot = home_slot
        self.refuse = refuse
        self._incoming: list[MissionItem] | None = None
        self._type = 0
        self._count = 0
        self._last_request = 0.0
        self._last_new_item = 0.0

    def deadline(self) -> float:
        if self._incoming is None:
            return float("inf")
        return min(self._last_request + self.rerequest, self._last_new_item + self.give_up)

    def tick(self, now: float) -> list[MissionMessage]:
        if self._incoming is None:
            return []
        if now >= self._last_new_item + self.give_up:
            self._incoming = None
            return [MissionAck(MissionResult.MAV_MISSION_OPERATION_CANCELLED, self._type)]
        if now >= self._last_request + self.rerequest:
            return [self._request(now)]
        return []

    def _request(self, now: float) -> MissionRequest:
        self._last_request = now
        assert self._incoming is not None
        return MissionRequest(len(self._incoming), self._type, legacy=True)

    def receive(self, msg: MissionMessage, now: float) -> list[MissionMessage]:
        if isinstance(msg, MissionCount):
            if self.refuse is not None:
                return [MissionAck(self.refuse, msg.mission_type)]
            if msg.count == 0:
                self.lists[msg.mission_type] = []
                return [MissionAck(ACCEPTED, msg.mission_type)]
            self._incoming, self._type, self._count = [], msg.mission_type, msg.count
            self._last_new_item = now
            return [self._request(now)]
        if isinstance(msg, MissionItem):
            return self._receive_item(msg, now)
        if isinstance(msg, MissionRequestList):
            return [MissionCount(len(self.lists.get(msg.mission_type, [])), msg.mission_type)]
        if isinstance(msg, MissionRequest):
            items = self.lists.get(msg.mission_type, [])
            return [items[msg.seq]] if msg.seq < len(items) else []
        if isinstance(msg, MissionClearAll):
            self.lists[msg.mission_type] = []
            return [MissionAck(ACCEPTED, msg.mission_type)]
        return []

    def _receive_item(self, item: MissionItem, now: float) -> list[MissionMessage]:
        if self._incoming is None:  # as ArduPilot answers an item it is not receiving
            return [MissionAck(MissionResult.MAV_MISSION_ERROR, item.mission_type)]
        if item.seq != len(self._incoming):
            return [MissionAck(MissionResult.MAV_MISSION_INVALID_SEQUENCE, item.mission_type)]
        self._incoming.append(item)
        self._last_new_item = now
        if len(self._incoming) < self._count:
            return [self._request(now)]
        received, self._incoming = self._incoming, None
        if self.home_slot and item.mission_type == MissionType.MISSION:
            received[0] = MissionItem(seq=0, frame=0, command=16, x=-353632621, y=1491652374,
                                      z=584.0)
        self.lists[item.mission_type] = received
        return [MissionAck(ACCEPTED, item.mission_type)]


class LossyLink:
    """Carries messages both ways with a fixed latency, dropping each with probability loss."""

    def __init__(self, rng: random.Random, loss_up: float, loss_down: float,
                 latency: float = 0.005) -> None:
        self.rng = rng
        self.loss_up = loss_up
        self.loss_down = loss_down
        self.latency = latency
        self.queue: list[tuple[float, int, str, MissionMessage]] = []
        self._order = 0
        self.sent = 0

    def post(self, now: float, to: str, msgs: list[MissionMessage]) -> None:
        loss = self.loss_up if to == "vehicle" else self.loss_down
        for msg in msgs:
            self.sent += 1
            if self.rng.random() >= loss:
                self._order += 1
                heapq.heappush(self.queue, (now + self.latency, self._order, to, msg))


def run(transfer: Transfer, vehicle: MissionResponder, link: LossyLink, limit: float = 600.0
        ) -> float:
    """Drive ``transfer`` against ``vehicle`` until it ends; returns the simulated duration."""
    now = 0.0
    link.post(now, "vehicle", transfer.start(now))
    while not transfer.done:
        next_delivery = link.queue[0][0] if link.queue else float("inf")
        now = min(next_delivery, transfer.deadline, vehicle.deadline())
        assert now < limit, "the transfer neither finished nor failed"
        if link.queue and link.queue[0][0] <= now:
            _, _, to, msg = heapq.heappop(link.queue)
            if to == "vehicle":
                link.post(now, "gcs", vehicle.receive(msg, now))
            else:
                link.post(now, "vehicle", transfer.receive(msg, now))
        link.post(now, "vehicle", transfer.tick(now))
        link.post(now, "gcs", vehicle.tick(now))
    # Let the last messages land (a re-sent ACK, the vehicle's copy of our final ACK).
    while link.queue:
        when, _, to, msg = heapq.heappop(link.queue)
        if to == "vehicle":
            vehicle.receive(msg, when)
    return now


def mission(n: int, mission_type: int = MissionType.MISSION) -> list[MissionItem]:
    return [MissionItem(seq=i, frame=6, command=16, param1=0.5 * i, x=-353632621 + 1000 * i,
                        y=1491652374 - 700 * i, z=10.0 + i, mission_type=mission_type)
            for i in range(n)]


def test_hundred_uploads_of_hundred_items_survive_30_percent_loss_each_way() -> None:
    rng = random.Random(20250601)
    outcomes = []
    for _ in range(100):
        vehicle = MissionResponder()
        items = mission(100)
        upload = Upload(items, system_id=1)
        run(upload, vehicle, LossyLink(rng, 0.3, 0.3))
        download = Download(system_id=1)
        run(download, vehicle, LossyLink(rng, 0.3, 0.3))
        # A lost final ACK leaves the upload unconfirmed; the read-back settles it.
        delivered = upload.succeeded or upload.unconfirmed
        outcomes.append((delivered, download.succeeded, same_items(items, download.items)))
        if not upload.succeeded:
            assert upload.error is not None
            assert upload.error.result in ("TIMEOUT", "MAV_MISSION_ERROR")
    assert outcomes == [(True, True, True)] * 100


def test_unanswered_timeouts_offer_the_items_after_the_last_one_asked_for() -> None:
    items = mission(5)
    upload = Upload(items)
    upload.start(0.0)
    assert upload.receive(MissionRequest(0, legacy=True), 0.1) == [items[0]]
    # The vehicle may lack item 0, or hold it and have lost its request for 1 (or hold 1
    # too, and have lost its request for 2): each retry offers all three at once.
    now = upload.deadline
    assert [item.seq for item in upload.tick(now)] == [0, 1, 2]
    assert [item.seq for item in upload.tick(upload.deadline)] == [0, 1, 2]
    upload.receive(MissionAck(MissionResult.MAV_MISSION_INVALID_SEQUENCE), now)
    assert not upload.done  # ArduPilot's NACK of an item it did not expect ends nothing
    assert upload.receive(MissionRequest(3, legacy=True), now) == [items[3]]
    assert [i.seq for i in upload.tick(upload.deadline)] == [3, 4]
    upload.receive(MissionAck(ACCEPTED), upload.deadline)
    assert upload.succeeded and upload.progress == Progress(5, 5)


def test_without_offers_the_last_item_is_repeated_three_times_a_retry() -> None:
    items = mission(3)
    upload = Upload(items, offer_next=False)
    upload.start(0.0)
    upload.receive(MissionRequest(0), 0.1)
    assert [upload.tick(upload.deadline) for _ in range(2)] == [[items[0]] * 3] * 2


def test_unconfirmed_only_when_the_last_item_went_out() -> None:
    def silent_after(requests: list[int], n: int, offer_next: bool = True) -> Upload:
        upload = Upload(mission(n), offer_next=offer_next)
        upload.start(0.0)
        for seq in requests:
            upload.receive(MissionRequest(seq), 0.1)
        while not upload.done:
            upload.tick(upload.deadline)
        return upload

    assert silent_after([0, 1], 2).unconfirmed
    assert silent_after([0], 2).unconfirmed  # item 1 was offered: a read-back will tell
    assert not silent_after([0], 2, offer_next=False).unconfirmed
    assert not silent_after([0], 5).unconfirmed
    assert not silent_after([], 2).unconfirmed


def test_an_error_for_an_item_after_the_last_one_went_out_leaves_the_upload_unconfirmed(
        ) -> None:
    # ArduPilot answers MAV_MISSION_ERROR to an item that comes when it is no longer
    # receiving: an offer or repeat arriving after it stored the last item (its ACCEPTED
    # lost), or after it cancelled the upload. Only the read-back can tell which.
    items = mission(3)
    upload = Upload(items)
    upload.start(0.0)
    for seq in (0, 1, 2):
        upload.receive(MissionRequest(seq), 0.1)
    upload.tick(upload.deadline)
    upload.receive(MissionAck(MissionResult.MAV_MISSION_ERROR), upload.deadline)
    assert upload.done and upload.unconfirmed
    early = Upload(items, offer_next=False)
    early.start(0.0)
    early.receive(MissionRequest(0), 0.1)
    early.receive(MissionAck(MissionResult.MAV_MISSION_ERROR), 0.2)
    assert early.error is not None and early.error.result == "MAV_MISSION_ERROR"
    assert not early.unconfirmed  # items never sent: a failure, not a doubt


def test_a_lost_final_ack_is_given_up_on_after_five_retries_of_the_last_item() -> None:
    upload = Upload(mission(3), system_id=4)
    upload.start(0.0)
    for seq in (0, 1, 2):
        upload.receive(MissionRequest(seq), 0.1)
    now, retries = 0.1, []
    while not upload.done:
        now = upload.deadline
        retries.append([item.seq for item in upload.tick(now)])
    assert retries == [[2]] * 5 + [[]]
    assert now == pytest.approx(0.1 + 6 * 0.25)
    assert upload.unconfirmed and upload.error is not None and upload.error.seq == 2
    assert str(upload.error) == ("vehicle 4: mission upload failed: no MISSION_ACK after the "
                                 "last item (2), 5 retries 250 ms apart")


@pytest.mark.parametrize("mission_type", [MissionType.MISSION, MissionType.FENCE,
                                          MissionType.RALLY])
def test_upload_download_and_clear_each_mission_type(mission_type: MissionType) -> None:
    vehicle = MissionResponder()
    vehicle.lists[MissionType.MISSION] = mission(3)
    items = mission(5, mission_type)
    rng = random.Random(1)
    upload = Upload(items, mission_type)
    run(upload, vehicle, LossyLink(rng, 0, 0))
    assert upload.succeeded and vehicle.lists[mission_type] == items
    download = Download(mission_type)
    run(download, vehicle, LossyLink(rng, 0, 0))
    assert download.items == items
    clear = Clear(mission_type)
    run(clear, vehicle, LossyLink(rng, 0, 0))
    assert clear.succeeded and vehicle.lists[mission_type] == []
    if mission_type != MissionType.MISSION:
        assert vehicle.lists[MissionType.MISSION] == mission(3)  # other lists untouched


def test_upload_sends_items_with_the_transfer_mission_type() -> None:
    upload = Upload(mission(2), MissionType.FENCE)
    upload.start(0.0)
    (item,) = upload.receive(MissionRequest(1, MissionType.FENCE), 0.1)
    assert isinstance(item, MissionItem) and item.mission_type == MissionType.FENCE


def test_ardupilot_home_slot_is_placeholder_and_read_back_compares_from_item_one() -> None:
    vehicle = MissionResponder(home_slot=True)
    real = mission(4)
    sent = with_home_placeholder(real)
    assert [item.seq for item in sent] == [0, 1, 2, 3, 4]
    assert sent[1:] == [replace(item, seq=item.seq + 1) for item in real]
    rng = random.Random(2)
    run(Upload(sent), vehicle, LossyLink(rng, 0, 0))
    download = Download()
    run(download, vehicle, LossyLink(rng, 0, 0))
    assert download.items[0] != sent[0]  # the vehicle put its home there
    assert same_items(sent, download.items, skip_home=True)
    assert not same_items(sent, download.items)


def test_same_items_sees_a_changed_item_and_a_missing_one() -> None:
    items = mission(3)
    assert not same_items(items, [*items[:2], replace(items[2], z=11.5)])
    assert not same_items(items, items[:2])
    assert same_items(items, [replace(items[0], current=1), *items[1:]])


REFUSALS = [r for r in MissionResult if r != MissionResult.MAV_MISSION_ACCEPTED]


@pytest.mark.parametrize("result", REFUSALS, ids=lambda r: r.name)
def test_every_refusal_becomes_a_transfer_error_naming_the_result(result: MissionResult
                                                                  ) -> None:
    upload = Upload(mission(2), system_id=7)
    run(upload, MissionResponder(refuse=result), LossyLink(random.Random(3), 0, 0))
    assert not upload.succeeded
    assert isinstance(upload.error, MissionTransferError)
    assert upload.error.result == result.name
    assert upload.error.system_id == 7
    assert result.name in str(upload.error) and "vehicle 7" in str(upload.error)


def test_refusal_during_download_and_unknown_result_number() -> None:
    download = Download()
    download.start(0.0)
    download.receive(MissionCount(3), 0.1)
    download.receive(MissionAck(99), 0.2)
    assert download.error is not None and download.error.result == "MAV_MISSION_RESULT_99"
    assert result_name(4) == "MAV_MISSION_NO_SPACE"


def test_result_names_are_those_of_the_mavlink_definition() -> None:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    defined = {entry.name: value for value, entry
               in mavlink.enums["MAV_MISSION_RESULT"].items() if not entry.name.endswith("_END")}
    assert {r.name: r.value for r in MissionResult} == defined
    types = {entry.name: value for value, entry in mavlink.enums["MAV_MISSION_TYPE"].items()
             if not entry.name.endswith("_END")}
    assert {f"MAV_MISSION_TYPE_{t.name}": t.value for t in MissionType} == types


def test_silent_vehicle_fails_after_five_retries_of_mission_count() -> None:
    upload = Upload(mission(3), system_id=2)
    link = LossyLink(random.Random(4), loss_up=1.0, loss_down=1.0)
    took = run(upload, MissionResponder(), link)
    assert upload.error is not None and upload.error.result == "TIMEOUT"
    assert upload.error.seq is None
    assert "no request for item 0 after MISSION_COUNT (3), 5 retries 1500 ms apart" in str(
        upload.error)
    # MISSION_COUNT at 0 s, then a burst of three copies every 1.5 s: 5 retries.
    assert took == pytest.approx(6 * 1.5)
    assert upload.retransmissions == 5 and link.sent == 1 + 5 * 3


def test_a_vehicle_silent_mid_upload_fails_it_after_five_item_timeouts_naming_the_item(
        ) -> None:
    items = mission(5)
    upload = Upload(items, system_id=1)
    upload.start(0.0)
    upload.receive(MissionRequest(0), 0.1)
    upload.receive(MissionRequest(1), 0.2)
    assert upload.deadline == pytest.approx(0.45)
    assert upload.tick(0.4) == []
    now = 0.2
    while not upload.done:
        now = upload.deadline
        upload.tick(now)
    assert now == pytest.approx(0.2 + 6 * 0.25)  # not the whole transfer's 9 s
    error = upload.error
    assert error is not None and error.result == "TIMEOUT" and error.seq == 1
    assert str(error) == ("vehicle 1: mission upload failed: no request after item 1 (of 5), "
                          "5 retries 250 ms apart")
    assert not upload.unconfirmed


def test_any_answer_from_the_vehicle_starts_the_retries_over() -> None:
    upload = Upload(mission(5))
    upload.start(0.0)
    upload.receive(MissionRequest(0), 0.1)
    for _ in range(4):
        upload.tick(upload.deadline)
    now = upload.deadline
    upload.receive(MissionAck(MissionResult.MAV_MISSION_INVALID_SEQUENCE), now)
    ticks = 0
    while not upload.done:
        upload.tick(upload.deadline)
        ticks += 1
    assert ticks == 6 and upload.error is not None and upload.error.result == "TIMEOUT"


def test_download_retries_the_request_of_the_missing_item_and_names_it() -> None:
    download = Download(system_id=3)
    download.start(0.0)
    assert download.receive(MissionCount(4), 0.1) == [MissionRequest(0)]
    download.receive(mission(4)[0], 0.2)
    bursts = []
    while not download.done:
        bursts.append(download.tick(download.deadline))
    assert bursts == [[MissionRequest(1)] * 3] * 5 + [[]]
    error = download.error
    assert error is not None and error.seq == 1
    assert str(error) == ("vehicle 3: mission download failed: no item 1 (of 4) after "
                          "MISSION_REQUEST_INT, 5 retries 250 ms apart")


def test_a_duplicate_item_does_not_count_as_the_missing_one() -> None:
    items = mission(3)
    download = Download()
    download.start(0.0)
    download.receive(MissionCount(3), 0.1)
    download.receive(items[0], 0.2)
    assert download.receive(items[0], 0.25) == [MissionRequest(1)]
    assert download.progress == Progress(1, 3) and not download.done


def test_clear_is_retried_on_the_default_timeout() -> None:
    clear = Clear(MissionType.FENCE, system_id=2)
    assert clear.start(0.0) == [MissionClearAll(MissionType.FENCE)]
    assert clear.deadline == pytest.approx(1.5)
    assert clear.tick(1.5) == [MissionClearAll(MissionType.FENCE)] * 3
    while not clear.done:
        clear.tick(clear.deadline)
    assert str(clear.error) == ("vehicle 2: fence clear failed: no answer to MISSION_CLEAR_ALL "
                                "after 5 retries 1500 ms apart")


def test_out_of_order_and_duplicate_requests_are_answered_with_the_item_asked_for() -> None:
    items = mission(3)
    upload = Upload(items)
    assert upload.start(0.0) == [MissionCount(3)]
    answers = [upload.receive(MissionRequest(seq, legacy=seq == 1), 0.1 * k)
               for k, seq in enumerate([2, 0, 0, 1, 7])]
    assert answers == [[items[2]], [items[0]], [items[0]], [items[1]], []]
    assert upload.progress.done == 3 and not upload.done
    upload.receive(MissionAck(ACCEPTED), 0.6)
    assert upload.succeeded


def test_early_accept_from_a_previous_transfer_does_not_end_the_upload() -> None:
    upload = Upload(mission(2))
    upload.start(0.0)
    upload.receive(MissionAck(ACCEPTED), 0.01)
    assert not upload.done


def test_messages_of_another_mission_type_are_ignored() -> None:
    upload = Upload(mission(2))
    upload.start(0.0)
    assert upload.receive(MissionRequest(0, MissionType.FENCE), 0.1) == []
    upload.receive(MissionAck(MissionResult.MAV_MISSION_DENIED, MissionType.RALLY), 0.2)
    assert not upload.done


def test_progress_is_reported_as_items_move() -> None:
    vehicle = MissionResponder()
    upload = Upload(mission(10))
    seen = []
    link = LossyLink(random.Random(5), 0, 0)
    now = 0.0
    link.post(now, "vehicle", upload.start(now))
    while not upload.done:
        now, _, to, msg = heapq.heappop(link.queue)
        if to == "vehicle":
            link.post(now, "gcs", vehicle.receive(msg, now))
        else:
            link.post(now, "vehicle", upload.receive(msg, now))
            seen.append(upload.progress.done)
    assert seen == sorted(seen) and seen[-1] == 10 and upload.progress.total == 10
    assert len(set(seen)) == 10


def test_a_download_goes_on_through_an_error_ack_that_answers_a_late_upload_item() -> None:
    items = mission(2)
    download = Download()
    download.start(0.0)
    assert download.receive(MissionCount(2), 0.1) == [MissionRequest(0)]
    assert download.receive(MissionAck(MissionResult.MAV_MISSION_ERROR), 0.15) == []
    assert download.receive(items[0], 0.2) == [MissionRequest(1)]
    assert download.receive(items[1], 0.3) == [MissionAck(ACCEPTED)]
    assert download.succeeded and download.items == items
    refused = Download()
    refused.start(0.0)
    refused.receive(MissionAck(MissionResult.MAV_MISSION_DENIED), 0.1)  # a refusal stands
    assert refused.error is not None and refused.error.result == "MAV_MISSION_DENIED"


def test_download_of_an_empty_list_acknowledges_at_once() -> None:
    download = Download(MissionType.RALLY)
    assert download.start(0.0) == [MissionRequestList(MissionType.RALLY)]
    out = download.receive(MissionCount(0, MissionType.RALLY), 0.1)
    assert out == [MissionAck(ACCEPTED, MissionType.RALLY)]
    assert download.succeeded and download.items == [] and download.progress.total == 0


def test_download_keeps_the_first_copy_and_asks_for_what_is_missing() -> None:
    items = mission(3)
    download = Download()
    download.start(0.0)
    assert download.receive(MissionCount(3), 0.1) == [MissionRequest(0)]
    assert download.receive(items[1], 0.2) == [MissionRequest(0)]
    assert download.receive(items[0], 0.3) == [MissionRequest(2)]
    assert download.receive(replace(items[0], z=99.0), 0.4) == [MissionRequest(2)]
    assert download.receive(items[2], 0.5) == [MissionAck(ACCEPTED)]
    assert download.items == items


def test_items_must_be_numbered_from_zero() -> None:
    with pytest.raises(ValueError, match="seq"):
        Upload([replace(item, seq=item.seq + 1) for item in mission(2)])


def test_empty_upload_succeeds_on_the_ack() -> None:
    upload = Upload([])
    run(upload, MissionResponder(), LossyLink(random.Random(6), 0, 0))
    assert upload.succeeded and upload.progress.total == 0


# --- read-back by the vehicle's storage rules -------------------------------------------

LAT, LON = -353632610, 1491652300
NAN = math.nan

# Items uploaded to ArduCopter 4.7 SITL and what it read back (tests/interop measures them
# again): "kept" as its storage rules say, "wrapped" where a value did not fit its field.
ARDUCOPTER = json.loads((Path(__file__).parent / "data" / "arducopter_read_back.json")
                        .read_text())


def sent_and_read(case: dict) -> tuple[MissionItem, MissionItem]:
    command, frame, *params, x, y, z = case["sent"]
    frame_back, *params_back, x_back, y_back, z_back = case["read"]
    return (MissionItem(1, frame, command, 0, 1, *params, x, y, z),
            MissionItem(1, frame_back, command, 0, 1, *params_back, x_back, y_back, z_back))


def case_id(case: dict) -> str:
    return "-".join(f"{v:g}" for v in case["sent"][:6])


@pytest.mark.parametrize("case", ARDUCOPTER["kept"], ids=case_id)
def test_arducopter_read_back_is_what_ardupilots_rules_predict(case: dict) -> None:
    sent, read = sent_and_read(case)
    assert read_back_differences([sent], [read], ardupilot_form) == []


@pytest.mark.parametrize("case", ARDUCOPTER["kept"], ids=case_id)
def test_each_field_arducopter_keeps_is_checked(case: dict) -> None:
    # Nudging a field that ArduPilot keeps must be seen; a field it drops may read anything.
    sent, read = sent_and_read(case)
    form = ardupilot_form(sent)
    for name, expected in form.items():
        if expected is None or name == "frame":
            continue
        nudged = replace(read, **{name: getattr(read, name) + (1 if name in "xy" else 1.0)})
        (difference,) = read_back_differences([sent], [nudged], ardupilot_form)
        assert (difference.field, difference.read) == (name, getattr(nudged, name))
    for name in ("param1", "param2", "param3", "param4", "x", "y", "z"):
        if form.get(name) is None:
            changed = replace(read, **{name: 7 if name in "xy" else 7.0})
            assert read_back_differences([sent], [changed], ardupilot_form) == []


def test_frames_are_compared_by_family_where_arducopter_keeps_a_position() -> None:
    waypoint = MissionItem(1, 6, 16, x=LAT, y=LON, z=10.0)
    for frame_back, same in ((3, True), (6, True), (0, False), (5, False), (10, False)):
        back = replace(waypoint, frame=frame_back)
        assert (read_back_differences([waypoint], [back], ardupilot_form) == []) is same
    mission_frame = replace(waypoint, frame=2)  # MAV_FRAME_MISSION: a GLOBAL altitude
    assert read_back_differences([mission_frame], [replace(waypoint, frame=0)],
                                 ardupilot_form) == []
    yaw = MissionItem(1, 2, 115, param1=90.0, param3=1.0)  # no position: frame not kept
    assert read_back_differences([yaw], [replace(yaw, frame=0)], ardupilot_form) == []
    (local,) = read_back_differences([replace(waypoint, frame=1)], [waypoint], ardupilot_form)
    assert local.field == "frame" and "frame 1" in local.why


@pytest.mark.parametrize("case", ARDUCOPTER["wrapped"], ids=case_id)
def test_values_a_field_cannot_hold_are_differences_whatever_reads_back(case: dict) -> None:
    # ArduCopter SITL stores a hold of -1.5 s as 65535 and 70000 s as 4464 (the C
    # conversion wraps), and stops on a value beyond int32: none of them is what was meant.
    sent, read = sent_and_read(case)
    unstorable = {name for name, expected in ardupilot_form(sent).items()
                  if isinstance(expected, Unstorable)}
    assert unstorable
    for back in (read, sent):  # what came back, or the very value sent
        differences = read_back_differences([sent], [back], ardupilot_form)
        assert unstorable <= {d.field for d in differences}


def test_an_unstorable_value_says_what_the_field_holds() -> None:
    hold = MissionItem(1, 6, 16, param1=3e9, x=LAT, y=LON, z=10.0)
    (difference,) = read_back_differences([hold], [replace(hold, param1=0.0)], ardupilot_form)
    assert difference.describe() == ("item 1 command 16: param1 sent 3000000000, read back 0 "
                                     "(ArduPilot keeps whole numbers from 0 to 65535 here)")
    turns = MissionItem(1, 6, 18, param1=-2.0, param3=5.0, x=LAT, y=LON, z=10.0)
    assert ardupilot_form(turns)["param1"] == Unstorable("ArduPilot keeps 0 to 255 turns")
    high = MissionItem(1, 6, 16, x=LAT, y=LON, z=83000.0)
    assert isinstance(ardupilot_form(high)["z"], Unstorable)


def test_autocontinue_is_not_kept_by_ardupilot_but_compared_elsewhere() -> None:
    sent = MissionItem(1, 6, 16, autocontinue=0, x=LAT, y=LON, z=10.0)
    read = replace(sent, autocontinue=1)
    assert read_back_differences([sent], [read], ardupilot_form) == []
    (difference,) = read_back_differences([sent], [read], exact_form)
    assert difference.field == "autocontinue"


def test_a_command_without_a_rule_is_compared_by_command_only() -> None:
    sent = MissionItem(1, 2, 31000, param1=1.5, x=3)
    assert read_back_differences([sent], [replace(sent, param1=9.0, x=0)], ardupilot_form) == []
    (difference,) = read_back_differences([sent], [replace(sent, command=16)], ardupilot_form)
    assert (difference.field, difference.sent, difference.read) == ("command", 31000, 16)


def test_fence_and_rally_as_arducopter_keeps_them() -> None:
    # Measured: fence vertices read back in frame 0 without altitude, a circle keeps its
    # radius; rally points keep the frame's family and whole metres of altitude.
    vertex = MissionItem(0, 6, 5001, param1=3.0, x=LAT, y=LON, z=10.0,
                         mission_type=MissionType.FENCE)
    circle = MissionItem(1, 0, 5003, param1=50.5, param2=1.0, x=LAT, y=LON, z=7.0,
                         mission_type=MissionType.FENCE)
    rally = MissionItem(0, 6, 5100, param1=1.0, x=LAT, y=LON, z=12.7,
                        mission_type=MissionType.RALLY)
    fence_back = [replace(vertex, frame=0, autocontinue=0, z=0.0),
                  replace(circle, autocontinue=0, param2=0.0, z=0.0)]
    assert read_back_differences([vertex, circle], fence_back, ardupilot_form) == []
    rally_back = replace(rally, frame=3, autocontinue=0, param1=0.0, z=12.0)
    assert read_back_differences([rally], [rally_back], ardupilot_form) == []
    (moved,) = read_back_differences([rally], [replace(rally_back, z=13.0)], ardupilot_form)
    assert (moved.field, moved.sent, moved.read) == ("z", 12.7, 13.0)


def test_a_real_difference_names_item_field_and_both_values() -> None:
    sent = with_home_placeholder([
        MissionItem(0, 6, 22, z=10.0),
        MissionItem(1, 6, 16, param1=2.5, x=LAT, y=LON, z=10.0),
        MissionItem(2, 2, 178, param1=1.0, param2=5.0, param3=-1.0),
    ])
    read = [MissionItem(0, 0, 16, x=LAT, y=LON, z=584.0),  # home, not compared
            replace(sent[1], frame=3),
            replace(sent[2], frame=3, param1=3.0, y=LON + 10),  # changed behind tml's back
            replace(sent[3], frame=0, param2=4.0)]
    differences = read_back_differences(sent, read, ardupilot_form, skip_home=True)
    assert differences == [
        ItemDifference(2, 16, "param1", 2.5, 3.0, expected=2.0),
        ItemDifference(2, 16, "y", LON, LON + 10, expected=LON),
        ItemDifference(3, 178, "param2", 5.0, 4.0, expected=5.0),
    ]
    assert [d.describe(lambda c: {16: "NAV_WAYPOINT"}.get(c, str(c))) for d in differences] == [
        "item 2 NAV_WAYPOINT: param1 sent 2.5, read back 3 (expected 2)",
        f"item 2 NAV_WAYPOINT: y sent {LON}, read back {LON + 10}",
        "item 3 178: param2 sent 5, read back 4",
    ]
    (missing,) = read_back_differences(sent, [read[0], replace(sent[1], frame=3)],
                                       ardupilot_form, skip_home=True)
    assert missing.describe() == "2 items read back, 4 sent"


def test_exact_form_compares_every_field_as_float32_and_nan_as_itself() -> None:
    sent = MissionItem(0, 6, 16, param1=0.1, param4=NAN, x=LAT, y=LON, z=12.3)
    read = replace(sent, frame=3, param1=0.10000000149011612, z=12.300000190734863)
    assert read_back_differences([sent], [read]) == []
    assert [d.field for d in read_back_differences([sent], [replace(read, param4=0.0)])] == [
        "param4"]
    unstored = replace(read, param1=0.0)
    assert [d.field for d in read_back_differences([sent], [unstored])] == ["param1"]
