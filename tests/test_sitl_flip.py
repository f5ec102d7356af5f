"""FLIP as ArduCopter's ModeFlip: where it may start, which way it turns, when it ends."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as M

from sitl.flip import FLIP_RATE, FLIP_TIMEOUT, Flip
from sitl.params import AUTOPILOT_DEFAULTS, Params
from sitl.sticks import Sticks


def flip(*channels: int) -> Flip:
    sticks = Sticks(Params(AUTOPILOT_DEFAULTS, {"RC_OVERRIDE_TIME": -1}))
    msg = M.MAVLink_rc_channels_override_message(1, 1, *channels,
                                                 *[65535] * (8 - len(channels)))
    msg._header.srcSystem = 255
    sticks.override(msg, 0.0)
    return Flip(sticks)


def test_a_flip_starts_only_from_a_pilot_mode_flying_with_the_throttle_up():
    assert flip(1500, 1500, 1500).allowed("ALT_HOLD", True, 1.0)
    assert not flip(1500, 1500, 1500).allowed("GUIDED", True, 1.0)
    assert not flip(1500, 1500, 1500).allowed("ALT_HOLD", False, 1.0)
    assert not flip(1500, 1500, 1000).allowed("STABILIZE", True, 1.0)  # throttle down
    assert flip(1500, 1500, 1000).allowed("ALT_HOLD", True, 1.0)  # ALT_HOLD needs none
    assert not flip(1990, 1500, 1500).allowed("ALT_HOLD", True, 1.0)  # roll stick over


def test_one_turn_about_the_axis_the_sticks_choose_then_it_is_over():
    rolling = flip(1500, 1500, 1500)
    rolling.start("ALT_HOLD", 0.0)
    attitudes = []
    now = 0.0
    while (attitude := rolling.turn(0.05, True, now)) is not None:
        attitudes.append(attitude)
        now += 0.05
    assert len(attitudes) == int(360.0 / (FLIP_RATE * 0.05)) - 1  # 20 to 340 degrees, then over
    assert all(pitch == 0.0 for _, pitch in attitudes) and attitudes[0][0] > 0  # to the right
    pitching = flip(1500, 1800, 1500)  # pitch stick back: a pitch flip
    pitching.start("ALT_HOLD", 0.0)
    roll, pitch = pitching.turn(0.05, True, 0.0) or (None, None)
    assert roll == 0.0 and pitch and pitch > 0
    assert pitching.turn(0.05, False, 0.1) is None  # disarmed: over
    late = flip(1500, 1500, 1500)
    late.start("ALT_HOLD", 0.0)
    assert late.turn(0.05, True, FLIP_TIMEOUT + 0.1) is None
