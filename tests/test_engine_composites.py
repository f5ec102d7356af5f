"""The node lifecycle and the composites (tml.engine.composites), with scripted leaves."""

from __future__ import annotations

from test_engine_interpreter import hover, mission

from tml.engine.composites import Node, NodeStatus, ParallelNode, RepeatNode, SequenceNode
from tml.engine.context import Options, Run
from tml.vehicle import IdSource


class Scripted(Node):
    """A leaf that runs for ``steps`` ticks, then ends with ``outcome``; it writes what
    happens to it in ``said``."""

    def __init__(self, name: str, said: list[str], steps: int = 1,
                 outcome: NodeStatus = NodeStatus.SUCCESS) -> None:
        super().__init__()
        self.name, self.said, self.steps, self.outcome = name, said, steps, outcome

    def start(self) -> None:
        self.said.append(f"{self.name} start")

    def step(self) -> NodeStatus:
        self.steps -= 1
        return self.outcome if self.steps <= 0 else NodeStatus.RUNNING

    def end(self, status: NodeStatus, why: str) -> None:
        self.said.append(f"{self.name} {status.value}" + (f" ({why})" if why else ""))


class Told(SequenceNode):
    """A sequence that writes its own end in ``said``."""

    def __init__(self, run: Run, parts: list[Node], said: list[str]) -> None:
        super().__init__(run, len(parts), lambda i: parts[i])
        self.said = said

    def end(self, status: NodeStatus, why: str) -> None:
        super().end(status, why)
        self.said.append(f"sequence {status.value}")


def a_run() -> Run:
    return Run(mission(hover()), [1], Options(), {}, IdSource())


def test_a_sequence_starts_the_next_part_in_the_tick_the_previous_ends() -> None:
    said: list[str] = []
    sequence = Told(a_run(), [Scripted("a", said), Scripted("b", said, 2)], said)
    assert sequence.tick() is NodeStatus.RUNNING
    assert said == ["a start", "a success", "b start"]
    assert sequence.tick() is NodeStatus.SUCCESS
    assert said[-2:] == ["b success", "sequence success"]


def test_a_stop_goes_down_first_each_child_ending_before_its_parent() -> None:
    said: list[str] = []
    sequence = Told(a_run(), [Scripted("a", said, 5)], said)
    sequence.tick()
    sequence.stop("until")
    assert said == ["a start", "a invalid (until)", "sequence invalid"]
    assert sequence.status is NodeStatus.INVALID
    sequence.stop("again")  # a stopped node is not stopped twice
    assert len(said) == 3


def test_a_failure_stops_the_other_branches_and_carries_up() -> None:
    said: list[str] = []
    parallel = ParallelNode(a_run(), lambda: [
        Scripted("slow", said, 9), Scripted("bad", said, 1, NodeStatus.FAILURE)])
    assert parallel.tick() is NodeStatus.FAILURE
    assert said == ["slow start", "bad start", "bad failure",
                    "slow invalid (a sibling branch failed)"]


def test_first_stops_the_others_when_one_is_done() -> None:
    said: list[str] = []
    first = ParallelNode(a_run(), lambda: [Scripted("slow", said, 9), Scripted("quick", said, 1)],
                         first=True)
    assert first.tick() is NodeStatus.SUCCESS
    assert said == ["slow start", "quick start", "quick success",
                    "slow invalid (another branch finished first)"]


def test_repeats_follow_at_once_and_loop_rounds_at_the_next_step() -> None:
    run = a_run()
    task = mission('<task name="T"><repeat times="3"/><action name="WAIT"><argument '
                   'name="duration" value="1"/></action></task>').tasks[0]
    said: list[str] = []
    repeat = RepeatNode(run, task, {None: 1}, lambda first: Scripted("r", said), 1, 0.0)
    assert repeat.tick() is NodeStatus.SUCCESS and said.count("r start") == 3
    looped = mission('<task name="L"><loop/><action name="WAIT"><argument name="duration" '
                     'value="1"/></action></task>').tasks[0]
    said.clear()
    loop = RepeatNode(run, looped, {None: 1}, lambda first: Scripted("l", said), 1, 0.0)
    for _ in range(3):
        assert loop.tick() is NodeStatus.RUNNING
    assert said.count("l start") == 3
    decisions = [r.data for r in run.log.take().records if r.kind == "decision"]
    assert [d["iteration"] for d in decisions if "iteration" in d] == [2, 3]
    assert [d["round"] for d in decisions if "round" in d] == [2, 3]
