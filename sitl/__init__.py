"""A pure-Python MAVLink vehicle simulator that behaves like ArduCopter SITL."""

MAX_VEHICLES = 255
"""Vehicles one simulator serves at most: they take the system ids 1..N, and a MAVLink system
id is one byte."""
