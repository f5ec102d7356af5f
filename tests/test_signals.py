"""Stop signals before a command takes them over (tml.commands.signals.StopSignals)."""

from __future__ import annotations

import os
import signal

import pytest

from tml.commands.signals import AGAIN_AFTER, Stopped, StopSignals


def test_a_stop_is_raised_again_until_a_command_takes_it_and_then_no_more() -> None:
    # The defect: tml run caught the stop while it waited for a vehicle and said so, but on
    # a busy machine the stop raised again a second later came out of its clean-up, and the
    # last line said "tml: interrupted (SIGTERM)" instead of the run's own words.
    with StopSignals() as stops:
        with pytest.raises(Stopped) as raised:
            os.kill(os.getpid(), signal.SIGTERM)
        assert stops.received == "SIGTERM"
        # Armed: raised again in case a library swallowed it ...
        assert signal.getitimer(signal.ITIMER_REAL)[1] == AGAIN_AFTER
        raised.value.taken()
        # ... and no more once a command said it took it.
        assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
        with pytest.raises(Stopped):  # a new signal still stops
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
