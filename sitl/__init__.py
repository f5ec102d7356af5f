"""A pure-Python MAVLink vehicle simulator that behaves like ArduCopter SITL."""
