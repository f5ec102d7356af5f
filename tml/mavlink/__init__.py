"""MAVLink: the only part of tml that imports pymavlink (lazily)."""
