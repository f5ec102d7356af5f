"""Plans other tools read and write: QGroundControl ``.plan``, QGC WPL 110 waypoint files
(MAVProxy's ``wp load``), and KML / GeoJSON for map viewers.

:mod:`tml.plans.planned` turns a mission into the mission items it would fly
(:func:`~tml.plans.planned.plan_mission`); :mod:`tml.plans.qgc` and :mod:`tml.plans.wpl`
write and read the two plan formats, :mod:`tml.plans.maps` draws a plan and its world for
a map, and :mod:`tml.plans.imported` turns mission items read from a file back into a TML
mission.
"""
