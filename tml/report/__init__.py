"""Flight reports: what a flight log tells, as a picture (PNG, with matplotlib), an HTML page
with the picture and tables, or the flown tracks for map tools (GPX, KML).

:mod:`tml.report.flight` reads the log, :mod:`tml.report.figures` draws it,
:mod:`tml.report.pages` writes the page and :mod:`tml.report.tracks` the tracks.
"""
