"""Several ``tml serve`` instances on one PostgreSQL: leased vehicles, a fenced link, and
the runs of an instance that died continued by another.

Theory of operation
-------------------
Every instance opens a link to every vehicle (each vehicle's port takes several ground
stations, as ArduPilot's serial ports and the simulator's TCP ports do) and reads all
their telemetry, but *sends* only to the vehicles it owns, through
:class:`~tml.serve.lease.Leases`:

- **The lease.** The instance's row in ``cluster_instances`` is renewed every
  ``renew = lease / 3`` seconds (default 1 s of a 3 s lease) by a thread of
  :class:`Cluster` that does nothing else. A vehicle is owned through a row that names
  that session (:class:`ClusterHangar` takes it when a run, or an operator's command,
  needs the vehicle, and gives it back once the vehicle, held by nothing, shows itself
  disarmed).
- **Silence until leased.** The instance opens its links with every gate shut
  (``SessionOptions.fenced``): not even its HEARTBEAT goes out, no telemetry rate is
  asked, no parameter read. What opening a vehicle does is done when the instance first
  leases it (:meth:`ClusterHangar._prepare`).
- **The fence.** MAVLink has no field for a fencing token, so the fence is on the sender:
  every message to a vehicle passes :meth:`ClusterHangar.may_send` (the link's gate,
  :attr:`tml.mavlink.link.Link.gate`), which lets it through only while this process can
  *prove* its lease: the vehicle is owned by this session, and the monotonic clock is
  before ``started + lease - margin``, where ``started`` is when the last successful
  renewal was *sent* (before the server stamped it: the server's ``clock_timestamp()``
  at the update was later, so the real expiry is later than this bound). A renewal that
  fails, is late or hangs therefore closes the fence on time by itself; nothing needs
  to happen for the sends to stop. The ``margin`` (default ``lease / 6``, 0.5 s) covers
  a message already on its way when the fence closes and the difference of clock rates
  between this machine and the database over one lease (a few parts per million in
  practice); no agreement of wall clocks is assumed: the server's clock alone says
  when a lease has expired, the instance's monotonic clock only how long ago it renewed.
- **Takeover.** Another instance may take a vehicle only once the server's clock is past
  its owner's expiry, which is after the owner's fence closed. Each survivor looks every
  ``renew`` seconds for runs of instances whose lease has expired
  (:meth:`Leases.orphans`), marks one ``interrupted`` (one instance wins it) and
  continues it from its stored journal, as ``POST /runs/{id}/continue`` does
  (:meth:`tml.serve.service.Service.continue_run`): its vehicles are taken with new
  fencing tokens and its mission goes on where the log stood. A vehicle of a dead
  session still flying in no run that goes on (a run with roles, which is not
  continued; a vehicle returning after its run had ended) is leased and sent home
  (RTL) instead (:meth:`Cluster._rescue`).
- **Controls** of a run or a vehicle another instance flies are carried to it
  (:mod:`tml.serve.forward`, PostgreSQL's LISTEN/NOTIFY).

The lease must be well inside the vehicles' own GCS failsafe time (ArduPilot
FS_GCS_TIMEOUT, 5 s by default): a vehicle whose instance died hears no ground station
from the kill until the new owner's first HEARTBEAT, at most ``lease + renew`` plus the
new owner's start of the run; with a 3 s lease that is 4 s and a bit, inside 5 s.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from tml.errors import TmlError
from tml.serve.hangar import Hangar, VehicleTaken
from tml.serve.lease import ClusterError, Leases
from tml.vehicle import Vehicle

if TYPE_CHECKING:
    from tml.serve.forward import Answer, Forwarded
    from tml.serve.service import Service

JOIN_PATIENCE = 3.0  # leases to wait for an earlier process of this name to expire

log = logging.getLogger("tml.serve")


class VehicleLeased(VehicleTaken):
    """A vehicle a run asked for is owned by another instance of the cluster."""

    def __init__(self, vehicle_id: int, owner: str) -> None:
        TmlError.__init__(self, f"vehicle {vehicle_id} is leased by the service instance "
                                f"{owner!r}")
        self.vehicle_id, self.run_id, self.owner = vehicle_id, f"on {owner}", owner


class FailsafeMissing(VehicleTaken):
    """A vehicle whose own failsafe does nothing on a lost ground station, not flown
    (``--require-gcs-failsafe``)."""

    def __init__(self, vehicle_id: int, problem: str) -> None:
        TmlError.__init__(self, f"vehicle {vehicle_id}: {problem}: not flown "
                                "(--require-gcs-failsafe)")
        self.vehicle_id, self.run_id = vehicle_id, ""


class ClusterHangar(Hangar):
    """A hangar whose vehicles are held in the cluster's lease table too, and whose links
    send only what :meth:`may_send` lets through (see the module docstring)."""

    def __init__(self, vehicles: Sequence[Vehicle], clock: Callable[[], float],
                 leases: Leases, monotonic: Callable[[], float] = time.monotonic,
                 require_gcs_failsafe: bool = False) -> None:
        super().__init__(vehicles, clock)
        self.require_gcs_failsafe = require_gcs_failsafe
        self.leases = leases
        self.monotonic = monotonic
        self.margin = leases.lease / 6
        self.owned: dict[int, int] = {}  # vehicle id -> fencing token, this session's
        self.valid_until = 0.0  # monotonic time the fence closes (renewed())
        self._own_lock = threading.RLock()  # a take and a give-back never cross
        self._prepared: set[int] = set()  # vehicles asked for their telemetry (_prepare)
        for vehicle in vehicles:
            link = getattr(vehicle, "link", None)
            if link is not None:
                link.gate = self._gate(link)

    # --- the fence -----------------------------------------------------------------------

    def may_send(self, vehicle_id: int) -> bool:
        """Whether this instance can prove its lease of ``vehicle_id`` now."""
        return vehicle_id in self.owned and self.monotonic() < self.valid_until

    def renewed(self, sent: float) -> None:
        """A renewal sent at monotonic time ``sent`` succeeded: the fence stays open until
        ``sent + lease - margin``."""
        self.valid_until = max(self.valid_until, sent + self.leases.lease - self.margin)

    def lapsed(self) -> None:
        """The session's lease is gone: close the fence and forget every vehicle."""
        with self._own_lock:
            self.valid_until = 0.0
            self.owned.clear()

    def _gate(self, link: Any) -> Callable[[int], bool]:
        """The gate of one link: its vehicles by system id (a broadcast, such as the
        ground station's HEARTBEAT, goes out only when every vehicle on it is owned)."""
        on_link = {getattr(v, "system_id", 0): vid for vid, v in self.vehicles.items()
                   if getattr(v, "link", None) is link}

        def gate(target: int) -> bool:
            ids = list(on_link.values()) if target == 0 else \
                [vid for sid, vid in on_link.items() if sid == target]
            return bool(ids) and all(self.may_send(vid) for vid in ids)

        return gate

    def owner_elsewhere(self, vehicle_id: int) -> str | None:
        """The other instance that leases ``vehicle_id`` now, or None (this one does, or
        nobody): where an operator's command to it is carried (Service.command)."""
        if vehicle_id in self.owned:
            return None
        owner = self.leases.owners([vehicle_id]).get(vehicle_id)
        return owner if owner != self.leases.name else None

    # --- holding vehicles ----------------------------------------------------------------

    def claim(self, vehicle_ids: Iterable[int], run_id: str) -> None:
        """As :meth:`Hangar.claim`, each vehicle leased first (VehicleLeased when another
        instance owns one)."""
        wanted = list(vehicle_ids)
        with self._own_lock:
            for vid in wanted:
                holder = self.holder(vid)
                if holder is not None:
                    raise VehicleTaken(vid, holder)
            for vid in wanted:
                self._take(vid)
            super().claim(wanted, run_id)

    def claim_free(self, run_id: str, every: bool = False) -> list[int]:
        """As :meth:`Hangar.claim_free`, among the vehicles no other instance owns."""
        chosen: list[int] = []
        with self._own_lock:
            for vid in sorted(self.vehicles):
                if self.holder(vid) is not None:
                    continue
                try:
                    self._take(vid)
                except VehicleLeased:
                    continue
                super().claim([vid], run_id)
                chosen.append(vid)
                if not every:
                    break
        return chosen

    def give_back(self) -> list[int]:
        """Release the lease of every owned vehicle that no run holds and that shows
        itself disarmed (one flying on after its run ended, e.g. returning home, stays
        owned until it has landed); the vehicles released."""
        released = []
        with self._own_lock:
            for vid in list(self.owned):
                if self.holder(vid) is None and not self.vehicles[vid].state().armed:
                    self.leases.release(vid)
                    del self.owned[vid]
                    released.append(vid)
        return released

    def _take(self, vehicle_id: int) -> None:
        if vehicle_id in self.owned:
            return
        taken = self.leases.take(vehicle_id)
        if taken is None:
            owner = self.leases.owners([vehicle_id]).get(vehicle_id)
            raise VehicleLeased(vehicle_id, owner or f"{self.leases.name} (lease lapsed)")
        self.owned[vehicle_id] = taken.token
        log.warning("vehicle %d: leased by %s (token %d%s)", vehicle_id, self.leases.name,
                    taken.token, f", from {taken.previous}" if taken.previous else "")
        if vehicle_id not in self._prepared:
            try:
                self._prepare(vehicle_id)
            except FailsafeMissing:
                self.leases.release(vehicle_id)
                del self.owned[vehicle_id]
                raise

    def _prepare(self, vehicle_id: int) -> None:
        """What opening a vehicle does, done once it is first leased (the session opened it
        without a word: ``SessionOptions.fenced``): its telemetry rates asked, what it can
        do read; and a warning when its own failsafe would do nothing on a lost ground
        station (:func:`tml.run.clearance.failsafe_problem`), as ``tml serve`` says of every
        vehicle it opens (FailsafeMissing with ``require_gcs_failsafe``)."""
        from tml.run.clearance import failsafe_problem

        vehicle = self.vehicles[vehicle_id]
        prepare = getattr(vehicle, "prepare", None)
        if prepare is None:
            return
        try:
            prepare()
            problem = failsafe_problem(vehicle)
        except TmlError as error:  # asked again the next time it is leased
            log.warning("vehicle %d: telemetry not asked for: %s", vehicle_id, error)
            return
        if problem is not None:
            if self.require_gcs_failsafe:
                raise FailsafeMissing(vehicle_id, problem)
            log.warning("vehicle %d: %s", vehicle_id, problem)
        self._prepared.add(vehicle_id)


class Cluster:
    """The thread that renews an instance's lease, gives back idle vehicles and continues
    the runs of instances that died; see the module docstring."""

    def __init__(self, hangar: ClusterHangar, service: Service) -> None:
        self.hangar = hangar
        self.leases = hangar.leases
        self.service = service
        self.renew_period = self.leases.lease / 3
        self.adopted: list[tuple[str, str]] = []  # (interrupted run, its continuation)
        self._stop = threading.Event()
        # Two threads: a renewal is never held up by a takeover's start (which prepares
        # its vehicles, a round trip each) and the fence stays open meanwhile.
        self._threads = [threading.Thread(target=self._renewing, name="cluster lease",
                                          daemon=True),
                         threading.Thread(target=self._tending, name="cluster takeover",
                                          daemon=True)]

    def start(self) -> list[str]:
        """Join the cluster (waiting for an earlier process of this instance's name to
        expire), continue that process's runs, and renew from now on; the runs
        continued. Raises ClusterError when the name stays held by a live process."""
        end = time.monotonic() + JOIN_PATIENCE * self.leases.lease
        while True:
            sent = self.hangar.monotonic()
            if self.leases.join():
                self.hangar.renewed(sent)
                break
            if time.monotonic() > end:
                raise ClusterError(f"the instance name {self.leases.name!r} is held by a "
                                   "live service: give each instance its own --instance")
            time.sleep(self.renew_period)
        self._threads[0].start()
        continued = self._adopt(own=True)
        self._threads[1].start()
        return continued

    def stop(self) -> None:
        """Stop renewing and end this session (its vehicles are free at once); called
        once the service has stopped its runs."""
        self._stop.set()
        for thread in self._threads:
            if thread.is_alive():
                thread.join(5.0)
        try:
            self.leases.leave()
        except Exception as error:  # the lease then expires by itself
            log.warning("cluster: leaving: %s", error)
        self.hangar.lapsed()

    def status(self) -> dict[str, Any]:
        """The instance's part of the cluster, for ``GET /status``."""
        return {"session": self.leases.session, "lease": self.leases.lease,
                "fence_open": self.hangar.monotonic() < self.hangar.valid_until,
                "owned": {str(v): t for v, t in sorted(self.hangar.owned.items())},
                "adopted": [{"run": a, "continued_as": b} for a, b in self.adopted]}

    def _renewing(self) -> None:
        while not self._stop.wait(self.renew_period):
            try:
                self._renew()
            except Exception as error:  # a database blip: the fence closes itself
                log.warning("cluster: renewing the lease: %s", error)

    def _tending(self) -> None:
        while not self._stop.wait(self.renew_period):
            try:
                self.hangar.give_back()
                self._adopt()
                self._rescue()
            except Exception as error:  # the next round tries again
                log.warning("cluster: %s", error)

    def _rescue(self) -> None:
        """Send home each vehicle still flying whose owner died and that no run will go on
        with (a run with roles, a vehicle returning after its run had ended): leased by
        this instance, sent to RTL as an operator's command does, and kept until it has
        landed."""
        from tml.serve.service import RequestError

        abandoned = set(self.leases.abandoned()) & set(self.hangar.vehicles)
        if not abandoned:
            return
        flown = self.leases.in_runs(time.time() - 10 * self.leases.lease)
        for vid in sorted(abandoned - flown):
            if not self.hangar.vehicles[vid].state().armed:
                continue
            try:
                self.service.command(vid, "rtl")
            except RequestError as refused:
                if self.leases.owners([vid]):  # another survivor was first: its to send
                    continue
                log.error("cluster: vehicle %d, flying without its owner: %s", vid,
                          refused.message)
                continue
            log.warning("cluster: vehicle %d was flying without its owner: RTL sent by %s",
                        vid, self.leases.name)

    def _renew(self) -> None:
        sent = self.hangar.monotonic()
        if self.leases.renew():
            self.hangar.renewed(sent)
            return
        # The lease expired before it was renewed (this process stalled, or the database
        # was out of reach): other instances may own the vehicles by now.
        log.error("cluster: the lease of instance %s expired: every vehicle let go, runs "
                  "aborted; joining again", self.leases.name)
        self.hangar.lapsed()
        from tml.serve.service import RequestError

        for run_id in self.service.status().live_runs:
            with contextlib.suppress(RequestError):  # ended meanwhile
                self.service.abort(run_id, f"the lease of service instance "
                                           f"{self.leases.name} expired")
        sent = self.hangar.monotonic()
        if self.leases.join():
            self.hangar.renewed(sent)

    def _adopt(self, own: bool = False) -> list[str]:
        """Continue the orphan runs this instance wins; their new ids."""
        from tml.serve.service import RequestError

        continued = []
        for run_id in self.leases.orphans(own=own):
            if not self.leases.adopt(run_id, "its service instance stopped renewing its "
                                     "lease", time.time()):
                continue
            try:
                run = self.service.continue_run(run_id)
            except RequestError as refused:
                log.error("cluster: run %s not continued: %s", run_id, refused.message)
                self.leases.give_up(run_id, refused.message)
                continue
            self.adopted.append((run_id, run.id))
            continued.append(run.id)
            log.warning("cluster: run %s of a stopped instance continued as run %s on %s",
                        run_id, run.id, self.leases.name)
        return continued


@contextlib.contextmanager
def clustered(service: Service, hangar: ClusterHangar) -> Iterator[Cluster]:
    """Join the cluster with ``service`` (its vehicles in ``hangar``), controls of other
    instances' runs forwarded to them, until left; the runs of an earlier process of
    this instance are continued on entry (:attr:`Cluster.adopted`)."""
    from tml.serve.forward import TIMEOUT, Forwarder, Unanswered

    forwarder = Forwarder(hangar.leases.engine, hangar.leases.name, service.carry_out)
    forwarder.start()

    def forward(instance: str, request: Forwarded) -> Answer:
        # An operator's command waits for the run that held the vehicle to end, up to the
        # service's command timeout, there as here.
        wait = service.options.command_timeout + TIMEOUT if request.get("op") == "command" \
            else TIMEOUT
        try:
            return forwarder.ask(instance, request, wait)
        except Unanswered as silent:
            return 504, str(silent), {"instance": instance}

    service.forward = forward
    cluster = Cluster(hangar, service)
    try:
        cluster.start()
        yield cluster
    finally:
        service.forward = None
        cluster.stop()
        forwarder.stop()
