"""The interpreter engine: pure, I/O-free, driven by the runner with the time and states.

See :mod:`tml.engine.interpreter` for the theory of operation.
"""

from tml.engine.context import Options
from tml.engine.interpreter import Interpreter
from tml.engine.records import Change, Output, Record, Status, TaskState, View
from tml.engine.scripts import Limits
from tml.language.failures import FailureReason

__all__ = ["Change", "FailureReason", "Interpreter", "Limits", "Options", "Output", "Record",
           "Status", "TaskState", "View"]
