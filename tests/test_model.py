"""The language model (tml.language.model)."""

from __future__ import annotations

import pytest

from tml.errors import Location
from tml.language.model import Action, Argument, Mission, Task, normalize_name

HERE = Location("m.xml", 1, 1)


@pytest.mark.parametrize("written", ["relative point", "Relative-Point", "relative_point",
                                     "relativePoint", "  RELATIVE   POINT "])
def test_normalize_name(written: str) -> None:
    assert normalize_name(written) == "relative_point"


def test_walk_is_depth_first_in_document_order() -> None:
    leaf = lambda name, parent: Task(name, (*parent, name), HERE,  # noqa: E731
                                     action=Action("LAND", (), HERE))
    b = Task("b", ("a", "b"), HERE, children=(leaf("c", ("a", "b")),))
    a = Task("a", ("a",), HERE, children=(b, leaf("d", ("a",))))
    mission = Mission("m", HERE, (a, leaf("e", ())))
    assert [t.name for t in mission.walk()] == ["a", "b", "c", "d", "e"]
    assert b.children[0].path_name == "a/b/c"
    assert [action.name for _, action in mission.actions()] == ["LAND", "LAND", "LAND"]


def test_action_argument_lookup_is_normalized() -> None:
    action = Action("GO_TO_POINT", (Argument("relative point", "(1,0,0)", None, HERE),), HERE)
    assert action.argument("relative_point").value == "(1,0,0)"
    assert action.argument("coordinates") is None
