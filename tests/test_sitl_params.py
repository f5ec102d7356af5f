"""The parameter table and the parameter protocol answers, as ArduPilot gives them."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.params import (
    AUTOPILOT_DEFAULTS,
    COMPANION_DEFAULTS,
    INT16,
    REAL32,
    Params,
    UnknownParameter,
    param_replies,
)


def table() -> Params:
    return Params(AUTOPILOT_DEFAULTS, {"RTL_ALT": 2000})


def test_overrides_replace_defaults_and_unknown_names_are_refused():
    p = table()
    assert p["RTL_ALT"] == 2000.0
    with pytest.raises(UnknownParameter):
        Params(AUTOPILOT_DEFAULTS, {"NO_SUCH": 1})
    with pytest.raises(UnknownParameter):
        p.set("NO_SUCH", 1)


def test_values_are_stored_rounded_to_their_type():
    p = table()
    assert p.set("RTL_ALT", 1234.6) == 1235.0 and p["RTL_ALT"] == 1235.0  # an integer
    assert p.set("WPNAV_SPEED", 512.25) == 512.25  # a float


def test_request_list_reports_every_parameter_once_with_index_and_type():
    p = table()
    values = param_replies(p, M.MAVLink_param_request_list_message(1, 1))
    assert len(values) == len(p) and {v.param_count for v in values} == {len(p)}
    assert [v.param_index for v in values] == list(range(len(p)))
    assert [v.param_id for v in values] == list(p)
    assert all(v.param_type == p.type_of(v.param_id) for v in values)
    assert {p.type_of("MAV_SYSID"), p.type_of("WPNAV_SPEED")} == {INT16, REAL32}


def test_read_by_name_or_index_and_set_echoes_the_stored_value():
    p = table()
    (by_index,) = param_replies(p, M.MAVLink_param_request_read_message(1, 1, b"", 3))
    (by_name,) = param_replies(p, M.MAVLink_param_request_read_message(
        1, 1, by_index.param_id.encode(), -1))
    assert by_name.param_index == 3 and by_name.param_value == by_index.param_value
    assert param_replies(p, M.MAVLink_param_request_read_message(1, 1, b"", 9999)) == []
    (echo,) = param_replies(p, M.MAVLink_param_set_message(1, 1, b"LAND_SPEED", 77.7, 9))
    assert (echo.param_id, echo.param_value) == ("LAND_SPEED", 78.0)
    assert param_replies(p, M.MAVLink_param_set_message(1, 1, b"NOPE", 1, 9)) == []
    assert param_replies(p, M.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)) == []


def test_the_companion_has_a_switch_per_skill_off_at_start():
    c = Params(COMPANION_DEFAULTS)
    skills = ("AVOID_OBST", "RECOG_MARKERS", "RECOG_ARUCO", "SELF_LOCATE", "RECOG_ITEMS",
              "RECOG_BUCKETS")
    assert all(c[name] == 0 for name in skills)
    assert "AVOID_OBST" not in table()  # separate tables: the switches live on component 191
