"""Small builders for outgoing messages shared by the autopilot and the companion.

A message built by the model is addressed with its sender (system, component) in its
header, so that the server encodes each with the right source ids without knowing which
part of the vehicle produced it.
"""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

AUTOPILOT = mavlink.MAV_COMP_ID_AUTOPILOT1  # 1
COMPANION = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER  # 191


def stamp(msg: Any, system_id: int, component_id: int) -> Any:
    """Set ``msg``'s source ids and return it."""
    msg._header.srcSystem = system_id
    msg._header.srcComponent = component_id
    return msg


def statustext(severity: int, text: str) -> Any:
    """A STATUSTEXT, cut to the 50 characters the field holds."""
    return mavlink.MAVLink_statustext_message(severity, text.encode()[:50])


def targets(msg: Any, system_id: int, component_id: int) -> bool:
    """True when ``msg`` is for this system and component (or broadcast, or untargeted)."""
    system = getattr(msg, "target_system", 0)
    component = getattr(msg, "target_component", 0)
    return system in (0, system_id) and component in (0, component_id)
