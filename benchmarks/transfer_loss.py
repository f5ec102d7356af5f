"""Mission transfer through a lossy link: the success rate, analysed and simulated.

Each trial uploads N waypoints (plus ArduPilot's home slot) to the simulator's mission
server (``sitl.missions.MissionServer``, which answers as ArduPilot's MissionItemProtocol
does: a request again every second, the upload cancelled after 8 s without an item,
INVALID_SEQUENCE for an item it does not wait for, MAV_MISSION_ERROR for one that comes
after the end) and downloads them again, through a link that drops each message with the
given probability each way, on simulated time (5 ms latency). The transfers are tml's own
sans-IO machines (``tml.mavlink.mission``) with their default timeouts, retries and bursts.

An upload counts as delivered when it succeeded, or ended unconfirmed (its final ACK lost:
``Vehicle.upload`` then reads the mission back) with the vehicle holding every item; a
download when it read every item back as stored.

The analysis (docs/reliability.md, "Mission transfer"): an exchange fails only when its
first message and RETRIES bursts of COPIES messages all go unanswered, each answered with
probability a = (1 - loss_up) * (1 - loss_down), so q = (1 - a) ** (1 + RETRIES * COPIES);
N waypoints behind the home slot make N + 2 exchanges either way (the count, then each of
the N + 1 items), and a transfer succeeds with probability (1 - q) ** (N + 2). The plain
per-message rule (single retransmissions, as QGroundControl's PlanManager sends them) has
q = (1 - a) ** (1 + RETRIES).

    .venv/bin/python benchmarks/transfer_loss.py [--sizes 100 500] [--trials 1000] [--loss 0.3]
"""

from __future__ import annotations

import argparse
import heapq
import random
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sitl.items import MissionItem as StoredItem
from sitl.missions import MissionServer
from tml.mavlink.codec import decode, encode
from tml.mavlink.mission import (
    COPIES,
    RETRIES,
    Download,
    MissionItem,
    Transfer,
    Upload,
    ardupilot_form,
    read_back_differences,
    with_home_placeholder,
)

LATENCY = 0.005
HOME = StoredItem(seq=0, frame=0, command=16, current=0, autocontinue=1, param1=0.0,
                  param2=0.0, param3=0.0, param4=0.0, x=-353632621, y=1491652374, z=584.0,
                  mission_type=0)


def waypoints(n: int) -> list[MissionItem]:
    """N waypoints behind ArduPilot's home slot, as tml uploads them."""
    return with_home_placeholder([
        MissionItem(seq=i, frame=6, command=16, x=-353632621 + 1000 * i,
                    y=1491652374 - 700 * i, z=10.0 + i) for i in range(n)])


def transfer(machine: Transfer, vehicle: MissionServer, rng: random.Random, loss: float,
             start: float) -> float:
    """Run ``machine`` against ``vehicle`` on simulated time until it ends; returns the time."""
    queue: list[tuple[float, int, str, Any]] = []
    order = 0

    def post(now: float, to: str, msgs: list[Any]) -> None:
        nonlocal order
        for msg in msgs:
            if rng.random() >= loss:
                order += 1
                heapq.heappush(queue, (now + LATENCY, order, to, msg))

    now = start
    post(now, "vehicle", machine.start(now))
    while not machine.done:
        # The vehicle's own timers run every 10 ms (ArduPilot's are polled as often).
        now = min(queue[0][0] if queue else float("inf"), machine.deadline,
                  (int(now * 100 + 1e-6) + 1) / 100)
        if queue and queue[0][0] <= now:
            _, _, to, msg = heapq.heappop(queue)
            if to == "vehicle":
                post(now, "gcs", vehicle.handle(encode(msg, 1, 1), now))
            else:
                plain = decode(msg)
                if plain is not None:
                    post(now, "vehicle", machine.receive(plain, now))  # type: ignore[arg-type]
        post(now, "vehicle", machine.tick(now))
        post(now, "gcs", vehicle.tick(now))
    for when, _, to, msg in sorted(queue):  # what is still on its way lands
        if to == "vehicle":
            vehicle.handle(encode(msg, 1, 1), when)
    return now


def trial(n: int, rng: random.Random, loss: float) -> tuple[bool, bool]:
    """One upload and one download of ``n`` waypoints: (delivered, read back)."""
    vehicle = MissionServer(lambda: HOME)
    items = waypoints(n)
    upload = Upload(items, system_id=1)
    now = transfer(upload, vehicle, rng, loss, start=2.0)  # after the vehicle's boot
    stored = [decode(encode(_plain(item), 1, 1)) for item in vehicle.items()]
    holds = not read_back_differences(items, stored, ardupilot_form,  # type: ignore[arg-type]
                                      skip_home=True)
    delivered = (upload.succeeded or upload.unconfirmed) and holds
    download = Download(system_id=1)
    transfer(download, vehicle, rng, loss, start=now + 10.0)
    read = download.succeeded and download.items == stored
    return delivered, read


def _plain(item: StoredItem) -> MissionItem:
    return MissionItem(item.seq, item.frame, item.command, item.current, item.autocontinue,
                       item.param1, item.param2, item.param3, item.param4, item.x, item.y,
                       item.z, item.mission_type)


def analysis(n: int, loss: float, copies: int = COPIES, retries: int = RETRIES
             ) -> tuple[float, float]:
    """(upload, download) success probability for ``n`` waypoints (see the docstring)."""
    unanswered = 1 - (1 - loss) ** 2
    q = unanswered ** (1 + retries * copies)
    exchanges = n + 2  # the count, then the home slot and each waypoint
    return (1 - q) ** exchanges, (1 - q) ** exchanges


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 500])
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--loss", type=float, default=0.3, help="loss each way (0.3)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    print(f"loss {args.loss:.0%} each way, {args.trials} trials, {RETRIES} retries, "
          f"bursts of {COPIES}")
    print(f"{'items':>6} {'':9} {'analysis':>9} {'simulated':>10} {'ratio':>6} "
          f"{'plain rule':>10}")
    for n in args.sizes:
        started = time.perf_counter()
        outcomes = [trial(n, rng, args.loss) for _ in range(args.trials)]
        took = time.perf_counter() - started
        predicted = analysis(n, args.loss)
        plain = analysis(n, args.loss, copies=1)
        for index, name in enumerate(("upload", "download")):
            rate = sum(outcome[index] for outcome in outcomes) / args.trials
            ratio = rate / predicted[index] if predicted[index] else float("nan")
            print(f"{n:>6} {name:9} {predicted[index]:>9.2%} {rate:>10.2%} {ratio:>6.3f} "
                  f"{plain[index]:>10.2%}")
        print(f"{'':>6} ({took:.0f} s)")


if __name__ == "__main__":
    main()
