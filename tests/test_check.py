"""Semantic checks beyond the invalid corpus: warnings, aliases, and what must pass."""

from __future__ import annotations

from tml.validation import validate_file


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
