"""The interpreter engine: pure, I/O-free, driven by the runner with the time and state.

See :mod:`tml.engine.interpreter` for the theory of operation.
"""

from tml.engine.fleet import Fleet
from tml.engine.interpreter import Interpreter, Options, Output, Record, Status, TaskState, View
from tml.engine.scripts import Limits

__all__ = ["Fleet", "Interpreter", "Limits", "Options", "Output", "Record", "Status", "TaskState",
           "View"]
