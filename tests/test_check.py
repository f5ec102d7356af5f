"""Semantic checks beyond the invalid corpus: warnings, aliases, and what must pass."""

from __future__ import annotations

from pathlib import Path

import pytest

from tml.language.validation import validate_file


def run(body: str, extra: str = ""):
    data = f'<mission name="m">\n{extra}{body}</mission>\n'.encode()
    return validate_file("m.xml", data)


TAKE_OFF = '<task name="Take off"><action name="TAKE_OFF"/></task>\n'


def codes(result) -> list[str]:
    return [d.code for d in result.diagnostics]


def test_undeclared_detection_parameter_is_a_warning_only() -> None:
    result = run(TAKE_OFF + '<task name="Move if green"><condition parameter="observed color" '
                 'comparison="equal" value="green"/><action name="LAND"/></task>\n')
    assert codes(result) == ["W301"]
    assert result.valid() and not result.valid(strict=True)


def test_declared_detection_parameter_is_typed_and_silent() -> None:
    declared = '<parameter name="Item A found" type="boolean"/>\n'
    ok = run(TAKE_OFF + '<task name="t"><condition parameter="Item A found" comparison="equal" '
             'value="yes"/><action name="LAND"/></task>\n', declared)
    assert ok.diagnostics == []
    wrong = run(TAKE_OFF + '<task name="t"><condition parameter="Item A found" '
                'comparison="equal" value="perhaps"/><action name="LAND"/></task>\n', declared)
    assert codes(wrong) == ["E224"]


def test_aerostack_spellings_are_accepted() -> None:
    result = run(
        TAKE_OFF + '<task name="Phase"><task name="Hover"><action name="WAIT">'
        '<argument name="duration" value="3"/></action></task></task>\n'
        '<event_handling>\n'
        '<event name="low"><condition parameter="percentageBatteryCharge" comparison="less than"'
        ' value="20"/><condition currentTask="Phase/Hover"/><action name="LAND"/>'
        '<termination mode="ABORT_MISSION"/></event>\n'
        '<event name="seen"><condition parameter="RECOGNIZED_ARUCO_MARKERS" comparison="includes"'
        ' value="0"/><action name="FLIP"><argument name="direction" value="FRONT"/></action>'
        '<termination mode="REPEAT_TASK"/></event>\n'
        '</event_handling>\n')
    assert result.diagnostics == []


def test_label_set_by_an_event_may_be_read_by_a_guarded_task() -> None:
    # The IMAV 2016 pattern: an event memorizes, a task guarded by "known" reads.
    result = run(
        TAKE_OFF + '<task name="Explore"><action name="EXPLORE_SPACE"/></task>\n'
        '<task name="Go to item"><condition label="item" comparison="known" value="yes"/>'
        '<action name="GO_TO_POINT"><argument name="coordinates" label="item"/></action></task>\n'
        '<event_handling><event name="found"><condition current_task="Explore"/>'
        '<condition parameter="RECOGNIZED_ITEMS" comparison="includes" value="A"/>'
        '<action name="MEMORIZE_POINT"><argument name="coordinates" label="item"/></action>'
        '<termination mode="CONTINUE"/></event></event_handling>\n')
    assert result.diagnostics == []


def test_label_read_in_a_loop_after_it_is_stored_later_is_allowed() -> None:
    body = ('<task name="Loop"><repeat times="2"/>'
            '<task name="Go back"><condition label="spot" comparison="known" value="yes"/>'
            '<action name="GO_TO_POINT"><argument name="coordinates" label="spot"/></action></task>'
            '<task name="Remember"><action name="MEMORIZE_POINT">'
            '<argument name="coordinates" label="spot"/></action></task></task>\n')
    assert run(TAKE_OFF + body).diagnostics == []


def test_misspelt_label_gets_a_suggestion() -> None:
    result = run(
        TAKE_OFF + '<task name="Remember"><action name="MEMORIZE_POINT">'
        '<argument name="coordinates" label="door coordinates"/></action></task>\n'
        '<task name="Back"><action name="GO_TO_POINT">'
        '<argument name="coordinates" label="door cordinates"/></action></task>\n')
    assert codes(result) == ["E230"]
    assert "did you mean 'door coordinates'" in result.diagnostics[0].hint


def test_task_paths_disambiguate_duplicate_names() -> None:
    body = ('<task name="A"><task name="Take off"><action name="TAKE_OFF"/></task></task>\n'
            '<task name="B"><task name="Take off"><action name="TAKE_OFF"/></task></task>\n'
            '<event_handling><event name="e"><condition current_task="B/Take off"/>'
            '<termination mode="JUMP_TO_TASK" task="A/Take off"/></event></event_handling>\n')
    assert run(body).diagnostics == []


def test_current_task_parameter_value_is_checked() -> None:
    result = run(TAKE_OFF + '<event_handling><event name="e"><condition parameter="CURRENT_TASK"'
                 ' comparison="equal" value="Take of"/><termination mode="CONTINUE"/></event>'
                 '</event_handling>\n')
    assert codes(result) == ["E240"]
    assert "did you mean 'Take off'" in result.diagnostics[0].hint


def test_termination_task_without_jump_is_a_warning() -> None:
    result = run(TAKE_OFF + '<event_handling><event name="e"><termination mode="NEXT_TASK" '
                 'task="Take off"/></event></event_handling>\n')
    assert codes(result) == ["W304"]


def test_unknown_action_and_argument_suggestions() -> None:
    result = run(TAKE_OFF + '<task name="t"><action name="ROTATE_YAWW">'
                 '</action></task>\n<task name="u"><action name="WAIT">'
                 '<argument name="duraton" value="1"/></action></task>\n')
    hints = {d.code: d.hint for d in result.diagnostics}
    assert "ROTATE_YAW" in hints["E201"]
    assert "duration" in hints["E210"]


def test_all_problems_are_reported_not_only_the_first() -> None:
    result = run(TAKE_OFF + '<task name="a"><action name="FLY"/></task>\n'
                 '<task name="b"><repeat times="0"/><action name="LAND"/></task>\n'
                 '<task name="c"><skill name="X"/><action name="WAIT"/></task>\n')
    assert sorted(codes(result)) == ["E201", "E202", "E211", "E250"]
    assert [d.location.line for d in result.diagnostics] == sorted(
        d.location.line for d in result.diagnostics)


def test_mission_dispatch_allows_mission_items() -> None:
    body = ('<task name="Fly" dispatch="mission"><task name="Up"><action name="TAKE_OFF"/></task>'
            '<task name="Around"><action name="LOITER"><argument name="turns" value="2"/>'
            '</action></task><task name="Photo"><action name="CAPTURE_PHOTO"/></task></task>\n')
    assert run(body).diagnostics == []


def test_known_takes_yes_or_no() -> None:
    result = run(TAKE_OFF + '<task name="r"><action name="MEMORIZE_POINT"><argument '
                 'name="coordinates" label="x"/></action></task>\n'
                 '<task name="t"><condition label="x" comparison="known" value="1.5"/>'
                 '<action name="LAND"/></task>\n')
    assert codes(result) == ["E224"]


def test_condition_numbers_are_written_as_in_arguments() -> None:
    for bad in ("nan", "inf", "1_0", "0x10"):
        result = run(TAKE_OFF + f'<task name="t"><condition parameter="ALTITUDE" '
                     f'comparison="less than" value="{bad}"/><action name="LAND"/></task>\n')
        assert codes(result) == ["E224"], bad


def test_yes_no_words_are_the_same_everywhere() -> None:
    for word in ("on", "off", "yes", "no", "true", "false", "1", "0"):
        result = run(TAKE_OFF + f'<task name="t"><condition parameter="ARMED" comparison='
                     f'"equal" value="{word}"/><action name="EXPLORE_SPACE"><argument '
                     f'name="build_map" value="{word}"/></action></task>\n')
        assert result.diagnostics == [], word


def test_tested_label_that_is_never_stored() -> None:
    result = run(TAKE_OFF + '<task name="Remember"><action name="MEMORIZE_POINT"><argument '
                 'name="coordinates" label="door"/></action></task>\n<task name="t"><condition '
                 'label="dor" comparison="known" value="yes"/><action name="LAND"/></task>\n')
    assert codes(result) == ["E232"]
    assert "did you mean 'door'" in result.diagnostics[0].hint


def test_declared_parameter_names_are_trimmed_like_conditions() -> None:
    result = run(TAKE_OFF + '<task name="t"><condition parameter=" x " comparison="less than" '
                 'value="1"/><action name="LAND"/></task>\n',
                 '<parameter name="x " type="number"/>\n')
    assert result.diagnostics == []


# --- fleets -------------------------------------------------------------------------------

ROLES = ('<roles><role name="north" type="quadcopter"/>'
         '<role name="south" type="multicopter"/></roles>\n')
FLOWN = ('<task name="N" role="north"><action name="TAKE_OFF"/></task>\n'
         '<task name="S" role="south"><action name="TAKE_OFF"/></task>\n')


def found(result) -> list[tuple[str, int, int]]:
    return [(d.code, d.location.line, d.location.column) for d in result.diagnostics]


def test_a_fleet_mission_with_every_construct_passes() -> None:
    body = ('<task name="Round" composition="parallel" time_limit="600" release="north south">\n'
            '<loop><condition parameter="BATTERY_CHARGE_PERCENTAGE" role="north" '
            'comparison="greater than" value="30"/></loop>\n'
            '<task name="N" role="north"><wait_for><condition parameter="ALTITUDE" role="south" '
            'comparison="greater than" value="5"/></wait_for>'
            '<until><condition parameter="TASK_ELAPSED_TIME" comparison="greater than" '
            'value="60"/></until><action name="TAKE_OFF"/>'
            '<on_error><task name="Back"><action name="LAND"/></task></on_error></task>\n'
            '<task name="S" role="south" composition="choice">'
            '<task name="Low"><condition parameter="BATTERY_CHARGE_PERCENTAGE" '
            'comparison="less than" value="50"/><action name="LAND"/></task>'
            '<task name="Else"><action name="TAKE_OFF"/></task></task>\n'
            '</task>\n'
            '<event_handling><event name="low" role="north"><condition '
            'parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" value="20"/>'
            '<termination mode="END_MISSION"/></event></event_handling>\n')
    assert run(body, ROLES).diagnostics == []


def test_undeclared_role_names_are_errors_at_the_attribute() -> None:
    body = ('<task name="X" role="nort" release="sout"><condition parameter="ALTITUDE" '
            'role="west" comparison="less than" value="5"/><action name="TAKE_OFF"/></task>\n'
            + FLOWN +
            '<event_handling><event name="e" role="est"><termination mode="CONTINUE"/>'
            '</event></event_handling>\n')
    result = run(body, ROLES)
    assert found(result) == [("E270", 3, 16), ("E270", 3, 28), ("E270", 3, 75),
                             ("E270", 6, 33)]
    hints = [d.hint for d in result.diagnostics]
    assert "did you mean 'north'?" in hints[0] and "did you mean 'south'?" in hints[1]
    assert hints[2] == "declared roles: north, south"


def test_role_in_a_mission_without_roles_says_how_to_declare_it() -> None:
    result = run('<task name="t" role="scout"><action name="TAKE_OFF"/></task>\n')
    assert codes(result) == ["E270"]
    assert '<role name="scout"/>' in result.diagnostics[0].hint


def test_duplicate_role_unknown_type_and_unused_role() -> None:
    roles = ('<roles><role name="north" type="quadcoptr"/><role name="north"/>\n'
             '<role name="south" type="UAV"/><role name="spare" type="rover"/></roles>\n')
    result = run(FLOWN, roles)
    assert found(result) == [("E272", 2, 27), ("E271", 2, 51), ("W305", 3, 32)]
    assert "did you mean 'quadcopter'?" in result.diagnostics[0].hint


def test_region_polygon_must_be_simple() -> None:
    def region(corners: str) -> str:
        return (f'<roles><role name="north"><region><polygon>{corners}</polygon></region>'
                '</role><role name="south"/></roles>\n')
    square = ('<point north="0" east="0"/><point north="0" east="10"/>'
              '<point north="10" east="10"/><point north="10" east="0"/>')
    bowtie = ('<point north="0" east="0"/><point north="10" east="10"/>'
              '<point north="0" east="10"/><point north="10" east="0"/>')
    line = '<point north="0" east="0"/><point north="5" east="5"/><point north="9" east="9"/>'
    assert run(FLOWN, region(square)).diagnostics == []
    crossed = run(FLOWN, region(bowtie))
    assert found(crossed) == [("E273", 2, 35)]
    assert "self-intersection at north 5 m, east 5 m" in crossed.diagnostics[0].message
    flat = run(FLOWN, region(line))
    assert codes(flat) == ["E273"] and "on one line" in flat.diagnostics[0].message


def test_with_several_roles_every_terminal_task_needs_one() -> None:
    body = FLOWN + ('<task name="Both"><task name="Who"><action name="LAND"/></task>'
                    '<on_error><task name="Handler"><action name="LAND"/></task></on_error>'
                    '</task>\n')
    assert [(c, line) for c, line, _ in found(run(body, ROLES))] == [("E274", 5), ("E274", 5)]
    # With one role, every task is flown by it.
    one = '<roles><role name="solo"/></roles>\n'
    assert run('<task name="t"><action name="LAND"/></task>\n', one).diagnostics == []


def test_vehicle_parameters_need_a_vehicle() -> None:
    body = ('<task name="Round" composition="parallel">\n'
            '<condition parameter="BATTERY_CHARGE_PERCENTAGE" comparison="less than" '
            'value="50"/>\n'
            '<condition parameter="BATTERY_CHARGE_PERCENTAGE" role="north" '
            'comparison="less than" value="50"/>\n'
            '<until><condition parameter="MISSION_ELAPSED_TIME" comparison="greater than" '
            'value="60"/></until>\n'
            '<wait_for><condition parameter="LANDED" comparison="equal" value="yes"/>'
            '</wait_for>\n' + FLOWN + '</task>\n')
    assert found(run(body, ROLES)) == [("E275", 4, 1), ("E275", 7, 11)]
    # Without roles there is one vehicle per run, as before.
    classic = ('<task name="t"><condition parameter="LANDED" comparison="equal" value="yes"/>'
               '<action name="TAKE_OFF"/></task>\n')
    assert run(classic).diagnostics == []


def test_composition_needs_sub_tasks() -> None:
    result = run('<task name="t" composition="first"><action name="TAKE_OFF"/></task>\n')
    assert found(result) == [("E280", 2, 16)]


def test_choice_branches_after_an_unconditional_one_are_never_chosen() -> None:
    body = ('<task name="c" composition="choice">\n'
            '<task name="a"><condition parameter="ALTITUDE" comparison="less than" value="5"/>'
            '<action name="TAKE_OFF"/></task>\n'
            '<task name="b"><action name="LAND"/></task>\n'
            '<task name="d"><action name="LAND"/></task>\n</task>\n')
    result = run(body)
    assert found(result) == [("W306", 5, 1)]
    assert "'b' before it has no condition" in result.diagnostics[0].message
    assert result.valid() and not result.valid(strict=True)


def test_current_task_makes_no_sense_in_gates() -> None:
    for tag in ("wait_for", "until", "loop"):
        body = (TAKE_OFF + f'<task name="t">\n<{tag}><condition current_task="Take off"/>'
                f'</{tag}><action name="LAND"/></task>\n')
        assert found(run(body)) == [("E281", 4, len(tag) + 3)], tag


def test_gate_conditions_get_the_ordinary_checks() -> None:
    body = (TAKE_OFF + '<task name="t"><until><condition parameter="ALTITUD" '
            'comparison="less than" value="x"/></until><action name="LAND"/></task>\n')
    assert codes(run(body)) == ["E225"]


def test_empty_until_and_wait_for_are_errors() -> None:
    for tag in ("wait_for", "until"):
        result = run(TAKE_OFF + f'<task name="t">\n  <{tag}/><action name="LAND"/></task>\n')
        assert found(result) == [("E282", 4, 3)], tag
    forever = run(TAKE_OFF + '<task name="t"><loop/><action name="LAND"/></task>\n')
    assert forever.diagnostics == []


def test_jump_to_task_is_refused_when_branches_exist() -> None:
    events = ('<event_handling><event name="e"><termination mode="JUMP_TO_TASK" '
              'task="Take off"/></event></event_handling>\n')
    assert run(TAKE_OFF + events).diagnostics == []
    with_roles = run(FLOWN.replace('"N"', '"Take off"') + events, ROLES)
    assert found(with_roles) == [("E283", 5, 46)]
    timed = run(TAKE_OFF.replace('name="Take off"', 'name="Take off" time_limit="5"') + events)
    assert codes(timed) == ["E283"]


def test_mission_dispatch_cannot_hold_orchestration_or_several_roles() -> None:
    orchestrated = ('<task name="Plan" dispatch="mission"><task name="a" time_limit="9">'
                    '<action name="TAKE_OFF"/></task></task>\n')
    result = run(orchestrated)
    assert found(result) == [("E261", 2, 19)]
    assert "'a' (line 2) in it uses orchestration" in result.diagnostics[0].message
    mixed = ('<task name="Plan" dispatch="mission" role="north"><task name="a">'
             '<action name="TAKE_OFF"/></task><task name="b" role="south">'
             '<action name="LAND"/></task></task>\n')
    assert codes(run(mixed, ROLES)) == ["E261"]
    # A sub-tree flown by command inside the plan is not part of it.
    carved = ('<task name="Plan" dispatch="mission"><task name="a"><action name="TAKE_OFF"/>'
              '</task><task name="b" dispatch="command" time_limit="9"><action name="LAND"/>'
              '</task></task>\n')
    assert run(carved).diagnostics == []
    # ... but a plan inside that sub-tree is checked on its own.
    nested = carved.replace('<action name="LAND"/></task></task>',
                            '<task name="c" dispatch="mission" composition="first">'
                            '<task name="d"><action name="LAND"/></task></task></task></task>')
    assert found(run(nested)) == [("E261", 2, 149)]


def test_on_error_tasks_are_checked_and_share_names_with_sub_tasks() -> None:
    body = ('<task name="p"><task name="a"><action name="TAKE_OFF"/></task>\n'
            '<on_error><task name="a"><action name="LANDD"/></task></on_error></task>\n')
    assert sorted(codes(run(body))) == ["E201", "E244"]


def test_handler_tasks_can_be_named_by_path() -> None:
    body = ('<task name="p"><task name="a"><action name="TAKE_OFF"/></task>\n'
            '<on_error><task name="back"><action name="LAND"/></task></on_error></task>\n'
            '<event_handling><event name="e"><condition current_task="p/back"/>'
            '<termination mode="CONTINUE"/></event></event_handling>\n')
    assert run(body).diagnostics == []


def test_labels_in_side_by_side_branches_have_no_order() -> None:
    body = ('<task name="p" composition="parallel">'
            '<task name="go"><action name="GO_TO_POINT"><argument name="coordinates" '
            'label="spot"/></action></task>'
            '<task name="mark"><action name="MEMORIZE_POINT"><argument name="coordinates" '
            'label="spot"/></action></task></task>\n')
    assert run(body).diagnostics == []
    sequential = body.replace(' composition="parallel"', '')
    assert codes(run(sequential)) == ["E231"]


def test_mission_arguments_arducopter_does_not_keep_are_warnings() -> None:
    def mission_task(action: str) -> str:
        return (TAKE_OFF + f'<task name="Plan" dispatch="mission"><task name="a">{action}'
                '</task></task>\n')

    def loiter(*arguments: str) -> str:
        return '<action name="LOITER">' + "".join(
            f'<argument name="{n}" value="{v}"/>' for n, v in (a.split("=") for a in arguments)
        ) + "</action>"

    timed = run(mission_task(loiter("duration=30", "radius=8")))
    assert codes(timed) == ["W307"] and "NAV_LOITER_TIME" in timed.diagnostics[0].message
    assert timed.valid() and not timed.valid(strict=True)
    # Kept by ArduPilot (turns; NAV_LOITER_UNLIM keeps its radius, for a fixed wing to
    # circle), or left to the autopilot (no radius written): silent.
    assert codes(run(mission_task(loiter("turns=2", "radius=8")))) == []
    assert codes(run(mission_task(loiter("radius=8")))) == []
    assert codes(run(mission_task(loiter("duration=30")))) == []
    required = run(mission_task('<action name="LANDING_POINT"><argument name="coordinates" '
                                'value="(0, 0, 0)"/><argument name="precision_mode" '
                                'value="required"/></action>'))
    assert codes(required) == ["W308"] and "PLND_ENABLED" in required.diagnostics[0].message
    assert codes(run(mission_task('<action name="RETURN_HOME_AND_LAND"><argument '
                                  'name="land_mode" value="opportunistic"/></action>'))) == []
    # Flown with commands, the same actions are flown as written.
    assert codes(run(TAKE_OFF + f'<task name="a">{loiter("duration=30", "radius=8")}</task>\n'
                     )) == []


def test_an_unknown_parameter_is_said_even_without_a_comparison() -> None:
    result = run(TAKE_OFF + '<task name="t"><condition parameter="BATERY_CHARGE_PERCENTAGE" '
                 'value="30"/><action name="LAND"/></task>\n')
    assert codes(result) == ["E221", "E225"]


def _raw(*arguments: tuple[str, str]) -> str:
    written = "".join(f'<argument name="{n}" value="{v}"/>' for n, v in arguments)
    return f'<action name="MISSION_ITEM">{written}</action>'


def test_a_raw_mission_item_flies_only_in_a_mission_dispatch() -> None:
    jump = _raw(("command", "DO_JUMP"), ("frame", "MISSION"), ("param1", "1"))
    assert codes(run(TAKE_OFF + f'<task name="j">{jump}</task>\n')) == ["E262"]
    assert codes(run(TAKE_OFF + f'<task name="p" dispatch="mission"><task name="j">{jump}'
                     '</task></task>\n')) == []


def test_a_raw_mission_items_x_and_y_are_what_an_item_carries() -> None:
    def raw(frame: str, x: str) -> list[str]:
        item = _raw(("command", "16"), ("frame", frame), ("param5", x))
        return codes(run(TAKE_OFF + f'<task name="p" dispatch="mission"><task name="w">{item}'
                         '</task></task>\n'))

    assert raw("GLOBAL_RELATIVE_ALT", "36.5") == []
    assert raw("GLOBAL_RELATIVE_ALT", "91") == ["E263"]
    assert raw("MISSION", "2.5") == ["E263"]
    assert raw("MISSION", "3000000000") == ["E263"]
    assert raw("MISSION", "-7") == []


def test_a_raw_mission_item_without_its_command_is_one_error() -> None:
    item = _raw(("frame", "GLOBAL_RELATIVE_ALT"), ("param5", "36.5"))
    assert codes(run(TAKE_OFF + f'<task name="p" dispatch="mission"><task name="w">{item}'
                     '</task></task>\n')) == ["E211"]


def test_a_command_number_mavlink_does_not_define_is_a_warning() -> None:
    item = _raw(("command", "116"), ("frame", "2"))
    result = run(TAKE_OFF + f'<task name="p" dispatch="mission"><task name="w">{item}'
                 '</task></task>\n')
    assert codes(result) == ["W309"] and result.valid()


def test_aerostacks_mission_as_shipped_validates_with_a_warning_per_twin() -> None:
    # Aerostack's config/drone1/mission_specification_file.xml: three sibling tasks named
    # Stabilize under "Searching".
    path = Path(__file__).parent / "data" / "aerostack" / "mission_specification_file.xml"
    result = validate_file(path)
    assert result.valid() and not result.errors
    assert [(d.code, d.location.line) for d in result.diagnostics] == [("W310", 45),
                                                                       ("W310", 55)]


def test_a_jump_to_a_name_twins_share_is_refused() -> None:
    twins = ('<task name="p"><task name="s"><action name="STABILIZE"/></task>'
             '<task name="s"><action name="STABILIZE"/></task></task>\n')
    jump = ('<event_handling><event name="e"><condition parameter="BATTERY_CHARGE_PERCENTAGE" '
            'comparison="less than" value="20"/><termination mode="JUMP_TO_TASK" '
            'task="{}"/></event></event_handling>\n')
    assert codes(run(TAKE_OFF + twins)) == ["W310"]
    for target in ("s", "p/s"):
        assert sorted(codes(run(TAKE_OFF + twins + jump.format(target)))) == ["E244", "W310"]


def test_aerostacks_later_format_is_named_as_such() -> None:
    result = run('<task_tree><behavior name="TAKE_OFF"/></task_tree>\n')
    assert codes(result) == ["E008"]
    assert "Aerostack's later mission format" in result.diagnostics[0].message


def test_values_an_autopilot_takes_but_look_odd_are_warnings() -> None:
    def raw(*arguments: tuple[str, str]) -> list[str]:
        item = _raw(*arguments)
        return codes(run(TAKE_OFF + f'<task name="p" dispatch="mission"><task name="w">{item}'
                         '</task></task>\n'))

    yaw = (("command", "CONDITION_YAW"), ("frame", "MISSION"))
    assert raw(*yaw, ("param1", "640")) == ["W311"]  # ArduCopter's FarOrigin test
    assert raw(*yaw, ("param1", "350")) == []
    high = (("command", "NAV_WAYPOINT"), ("frame", "GLOBAL_RELATIVE_ALT"), ("param5", "40.07"),
            ("param6", "-105.23"))
    assert raw(*high, ("param7", "11085.9")) == ["W311"]  # a rover's unused altitude
    assert raw(*high, ("param7", "NaN")) == []


def test_a_raw_mission_item_in_an_event_is_refused() -> None:
    jump = _raw(("command", "DO_JUMP"), ("frame", "MISSION"), ("param1", "1"))
    event = ('<event_handling><event name="e"><condition parameter="BATTERY_CHARGE_PERCENTAGE" '
             f'comparison="less than" value="20"/>{jump}<termination mode="ABORT_MISSION"/>'
             '</event></event_handling>\n')
    assert codes(run(TAKE_OFF + event)) == ["E262"]


# --- a condition on a parameter nothing provides (E227) ----------------------------------

LOW_BATTERY = ('<event_handling><event name="low">{condition}<action name="LAND"/>'
               '<termination mode="ABORT_MISSION"/></event></event_handling>\n')


def event_on(parameter: str, comparison: str = "less than", value: str = "30") -> str:
    return LOW_BATTERY.format(condition=f'<condition parameter="{parameter}" '
                                        f'comparison="{comparison}" value="{value}"/>')


def test_an_event_on_a_parameter_nothing_provides_is_an_error() -> None:
    # BATTERY_LEVEL is no built-in (BATTERY_CHARGE_PERCENTAGE is): the event never fires.
    result = run(TAKE_OFF + event_on("BATTERY_LEVEL"))
    assert [(d.code, d.location.line, d.location.column) for d in result.diagnostics] \
        == [("E227", 3, 35)]
    assert result.diagnostics[0].hint == "did you mean 'BATTERY_CHARGE_PERCENTAGE'?"
    assert not result.valid()


@pytest.mark.parametrize(("comparison", "value", "declared"), [
    ("less than", "30", "number"), ("greater than or equal to", "1", "number"),
    ("equal", "4.5", "number"), ("includes", "red", "set"), ("equal", "yes", "boolean"),
    ("not equal to", "north", "string"), ("known", "yes", "string")])
def test_the_hint_declares_a_type_that_fits_the_comparison(
        comparison: str, value: str, declared: str) -> None:
    body = TAKE_OFF + event_on("zorblax", comparison, value)
    found = run(body).diagnostics
    assert [d.code for d in found] == ["E227"]
    declaration = f'<parameter name="zorblax" type="{declared}"/>'
    assert found[0].hint == f"declare it if a companion computer reports it: {declaration}"
    assert run(body, declaration + "\n").diagnostics == []  # the hint, followed, works


def test_a_found_name_is_provided_by_the_skill_that_feeds_its_set() -> None:
    seen = event_on("Item A found", "equal", "yes")
    without = run(TAKE_OFF + seen).diagnostics
    assert [d.code for d in without] == ["E227"]
    assert "RECOGNIZED_ITEMS" in without[0].message
    assert without[0].hint.startswith('switch on RECOGNIZE_ITEMS with '
                                      '<skill name="RECOGNIZE_ITEMS"/>, or declare it')
    # Switched on anywhere (here on a task, not on the mission), the skill provides it,
    # as a yes/no.
    searching = ('<task name="Search"><skill name="RECOGNIZE_ITEMS"/><action name="WAIT">'
                 '<argument name="duration" value="5"/></action></task>\n')
    assert run(TAKE_OFF + searching + seen).diagnostics == []
    ordered = run(TAKE_OFF + searching + event_on("Item A found", "less than", "3"))
    assert [d.code for d in ordered.diagnostics] == ["E223"]


def test_the_papers_imav_mission_needs_no_declaration_for_what_its_skills_feed() -> None:
    # The paper's Appendix A reads "Item A found" and "Bucket A found" in events, with no
    # <parameter> (TML as published has none): RECOGNIZE_ITEMS and RECOGNIZE_BUCKETS,
    # switched on by its tasks, feed them.
    import re

    text = (Path(__file__).parent.parent / "missions" / "imav2016.xml").read_text()
    undeclared = re.sub(r"<parameter name=[^>]*/>", "", text)
    assert "<parameter" not in undeclared and 'parameter="Item A found"' in undeclared
    assert validate_file("imav2016.xml", undeclared.encode()).diagnostics == []
    without_skill = undeclared.replace('<skill name="RECOGNIZE_BUCKETS"/>', "")
    found = validate_file("imav2016.xml", without_skill.encode()).diagnostics
    assert [(d.code, d.message.split(":")[0]) for d in found] == [
        ("E227", "nothing provides parameter 'Bucket A found'")]


@pytest.mark.parametrize("where", ["wait_for", "until"])
def test_a_gate_on_a_parameter_nothing_provides_is_an_error(where: str) -> None:
    body = (TAKE_OFF + f'<task name="Hover"><{where}><condition parameter="observed color" '
            f'comparison="equal" value="green"/></{where}><action name="WAIT">'
            '<argument name="duration" value="5"/></action></task>\n')
    assert codes(run(body)) == ["E227"]


def test_only_the_papers_guard_stays_a_warning() -> None:
    # Example 2 of the paper, as written: a guard comparing a word. Compared as a number, or
    # near a declared name (a misspelling), it is an error.
    guard = ('<task name="Move if green"><condition parameter="{name}" comparison="{how}" '
             'value="{value}"/><action name="LAND"/></task>\n')
    paper = guard.format(name="observed color", how="equal", value="green")
    assert codes(run(TAKE_OFF + paper)) == ["W301"]
    assert run(TAKE_OFF + paper).diagnostics[0].hint == \
        ('declare it if something on the vehicle reports it: '
         '<parameter name="observed color" type="string"/>')
    number = guard.format(name="observed color", how="less than", value="3")
    assert codes(run(TAKE_OFF + number)) == ["E227"]
    misspelt = guard.format(name="observed colr", how="equal", value="green")
    declared = '<parameter name="observed color" type="string"/>\n'
    found = run(TAKE_OFF + misspelt, declared).diagnostics
    assert [(d.code, d.hint) for d in found] == [("E227", "did you mean 'observed color'?")]


MISSIONS = sorted((Path(__file__).parent.parent / "missions").glob("*.xml"))


def _parameter_conditions(path: Path) -> list[tuple[str, int, int]]:
    """Each parameter a mission's conditions read, with the line and column of the first
    condition that reads it."""
    from tml.language.model import ConditionKind

    mission = validate_file(path).mission
    assert mission is not None
    conditions = [c for task in mission.walk() for c in (
        *task.conditions, *task.wait_for, *task.until,
        *(task.loop.conditions if task.loop else ()))] + [
        c for event in mission.events for c in event.conditions]
    first: dict[str, tuple[str, int, int]] = {}
    for c in sorted((c for c in conditions if c.kind is ConditionKind.PARAMETER),
                    key=lambda c: (c.location.line, c.location.column or 0)):
        first.setdefault(c.subject, (c.subject, c.location.line, c.location.column or 0))
    return list(first.values())


def _misspelt(name: str) -> str:
    """``name`` with one letter near its middle left out."""
    middle = len(name) // 2
    while not name[middle].isalpha():
        middle += 1
    return name[:middle] + name[middle + 1:]


MISSPELT = [(path, *read) for path in MISSIONS for read in _parameter_conditions(path)]


def test_most_example_missions_read_parameters() -> None:
    assert len({path for path, *_ in MISSPELT}) >= 15
    assert len(MISSPELT) >= 40


@pytest.mark.parametrize(("path", "name", "line", "column"), MISSPELT,
                         ids=[f"{p.name}:{n}" for p, n, *_ in MISSPELT])
def test_a_misspelt_parameter_in_every_example_mission_is_an_error(
        path: Path, name: str, line: int, column: int, tmp_path: Path) -> None:
    from tml.language import parameters

    wrong = _misspelt(name)
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    written = f'parameter="{name}"'
    at = next(i for i in range(line - 1, len(lines)) if written in lines[i])
    lines[at] = lines[at].replace(written, f'parameter="{wrong}"', 1)
    copy = tmp_path / path.name
    copy.write_text("".join(lines), encoding="utf-8")
    result = validate_file(copy)
    built_in = parameters.lookup(name)
    # A built-in misspelt is E225 (as before); any other name nothing provides, E227.
    expected = "E225" if built_in is not None else "E227"
    meant = built_in.name if built_in is not None else name
    assert [(d.code, d.location.file, d.location.line, d.location.column, d.hint)
            for d in result.errors] == [
        (expected, str(copy), line, column, f"did you mean {meant!r}?")]
