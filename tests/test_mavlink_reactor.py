"""tml.mavlink.reactor: one thread serving the files and duties of every connection."""

from __future__ import annotations

import socket
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

from tests.right_of_way import held_elsewhere
from tml.mavlink import reactor
from tml.timebase import SYSTEM, Lockstep, Timebase


def until(condition: Callable[[], bool], timeout: float = 30.0) -> None:
    """Wait for a state of the reactor's thread (generous: a state, not a duration)."""
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "the state never came"
        time.sleep(0.001)


class Pipe:
    """A connection the reactor serves: what comes on a socket pair, and a duty per period."""

    def __init__(self, period: float = 0.01, fail: bool = False) -> None:
        self.near, self.far = socket.socketpair()
        self.near.setblocking(False)
        self.period = period
        self.fail = fail
        self.read: list[bytes] = []
        self.duties_done = 0
        self.threads: set[str] = set()

    def fileno(self) -> int | None:
        return self.near.fileno() if self.near.fileno() >= 0 else None

    def readable(self, limit: int) -> bool:
        self.threads.add(threading.current_thread().name)
        if self.fail:
            raise RuntimeError("a bug in one connection")
        for _ in range(limit):
            try:
                data = self.near.recv(1)  # one "message" a byte: limits are reached
            except BlockingIOError:
                return False
            self.read.append(data)
        return True

    def duties(self, now: float) -> float:
        self.duties_done += 1
        return now + self.period

    def close(self) -> None:
        self.near.close()
        self.far.close()


def test_one_thread_serves_every_connection_and_ends_with_the_last() -> None:
    pipes = [Pipe() for _ in range(50)]
    served = [reactor.serve(p, SYSTEM) for p in pipes]
    assert len({id(r) for r in served}) == 1  # one reactor for the time base
    for i, p in enumerate(pipes):
        p.far.sendall(bytes([i]) * 3)
    until(lambda: all(len(p.read) == 3 for p in pipes))
    until(lambda: all(p.duties_done >= 2 for p in pipes))
    assert {name for p in pipes for name in p.threads} == {reactor.THREAD_NAME}
    thread = served[0].thread
    assert thread is not None
    for p in pipes:
        reactor.unserve(p, served[0])
        p.close()
    thread.join(30.0)
    assert not thread.is_alive()


def test_a_connection_let_go_of_is_not_touched_again() -> None:
    kept, dropped = Pipe(), Pipe()
    loop = reactor.serve(kept, SYSTEM)
    reactor.serve(dropped, SYSTEM)
    reactor.unserve(dropped, loop)
    done = dropped.duties_done
    dropped.far.sendall(b"x")
    kept.far.sendall(b"y")
    until(lambda: kept.read == [b"y"])
    time.sleep(0.05)  # the reactor's next rounds: nothing of the dropped one
    assert dropped.read == [] and dropped.duties_done == done
    reactor.unserve(kept, loop)
    for p in (kept, dropped):
        p.close()


def test_the_reactor_gives_way_between_turns_to_a_thread_with_the_right_of_way(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("tml.timebase.GIVE_WAY_LIMIT", 600.0)
    timebase = Timebase()
    first, second = Pipe(period=60.0), Pipe(period=60.0)
    loop = reactor.serve(first, timebase)
    reactor.serve(second, timebase)
    until(lambda: first.duties_done >= 1 and second.duties_done >= 1)  # then none for 60 s
    with held_elsewhere(timebase):
        first.far.sendall(b"1")
        until(lambda: first.read == [b"1"])
        second.far.sendall(b"2")
        time.sleep(0.05)  # the loop's next rounds, had it not given way after the first's turn
        assert second.read == []
    until(lambda: second.read == [b"2"])
    for p in (first, second):
        reactor.unserve(p, loop)
        p.close()


def test_the_interpreter_lock_is_handed_over_sooner_while_a_reactor_runs() -> None:
    before = sys.getswitchinterval()
    pipe = Pipe()
    loop = reactor.serve(pipe, Timebase())
    thread = loop.thread
    assert thread is not None
    assert sys.getswitchinterval() == min(before, reactor.SWITCH_INTERVAL)
    reactor.unserve(pipe, loop)
    pipe.close()
    thread.join(30)
    assert not thread.is_alive()
    assert sys.getswitchinterval() == before  # (another reactor still running: its value)


def test_a_connection_with_much_to_read_lets_the_others_have_their_turn() -> None:
    busy, quiet = Pipe(period=60.0), Pipe(period=60.0)
    busy.far.sendall(b"b" * (reactor.MESSAGES_AT_ONCE * 20))
    loop = reactor.serve(busy, SYSTEM)
    reactor.serve(quiet, SYSTEM)
    quiet.far.sendall(b"q")
    until(lambda: quiet.read == [b"q"])
    until(lambda: len(busy.read) == reactor.MESSAGES_AT_ONCE * 20)  # all of it, in turns
    for p in (busy, quiet):
        reactor.unserve(p, loop)
        p.close()


def test_a_connection_that_raises_is_reported_and_the_others_go_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    thread_errors: list[Any] = []
    monkeypatch.setattr(threading, "excepthook", thread_errors.append)
    broken, fine = Pipe(fail=True), Pipe()
    loop = reactor.serve(broken, SYSTEM)
    reactor.serve(fine, SYSTEM)
    broken.far.sendall(b"x")
    until(lambda: len(thread_errors) == 1)
    assert thread_errors[0].exc_type is RuntimeError
    fine.far.sendall(b"y")
    until(lambda: fine.read == [b"y"])
    for p in (broken, fine):
        reactor.unserve(p, loop)
        p.close()


def test_a_new_file_of_a_connection_is_watched() -> None:
    p = Pipe(period=0.01)
    loop = reactor.serve(p, SYSTEM)
    p.far.sendall(b"1")
    until(lambda: p.read == [b"1"])
    old = p.near
    near, far = socket.socketpair()  # dialled again: another socket
    near.setblocking(False)
    p.near, p.far = near, far
    old.close()
    until(lambda: p.duties_done >= 3)  # a duty after the change: the file is looked at
    p.far.sendall(b"2")
    until(lambda: p.read == [b"1", b"2"])
    reactor.unserve(p, loop)
    p.close()


def test_in_lock_step_time_waits_for_the_reactor_to_read_and_take_in() -> None:
    timebase: Timebase = Lockstep()
    assert isinstance(timebase, Lockstep)
    p = Pipe(period=1.0)
    loop = reactor.serve(p, timebase)
    until(timebase.settled)  # taken in, its first duty done, waiting on its socket
    assert p.duties_done == 1
    timebase.track("pipe")
    timebase.carried("pipe", 1)
    p.far.sendall(b"z")
    assert not timebase.settled()  # a byte in flight
    until(lambda: p.read == [b"z"])
    timebase.carried("pipe", -1)
    until(timebase.settled)
    timebase.advance(1.0)
    assert timebase.fire()  # the duty's deadline ends the reactor's wait
    until(lambda: p.duties_done == 2)
    until(timebase.settled)
    reactor.unserve(p, loop)
    p.close()
