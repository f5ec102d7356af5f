"""tml: read TML mission files and fly them on MAVLink vehicles.

The pipeline follows the data: ``parse`` (hardened XML -> model), ``schema`` (XSD),
``check`` (semantic rules), ``verify`` (physical feasibility), the interpreter engine,
and ``mavlink`` (the only place that speaks the wire protocol).
"""

__version__ = "0.1.0"
