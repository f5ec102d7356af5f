"""The report as one HTML page: the figure embedded, the outcome, and tables of the tasks (in
tree order, each with its round, and the event handlers' actions with the event that ran
them), of the photos and detections (where each vehicle was, in the map's frame), and of
what happened (events, autopilot messages, safety steps: their mission time and wall-clock
time), all drawn from the report's data (:class:`~tml.report.scene.Scene`), with nothing
fetched from anywhere: the page opens offline and can be mailed as it is."""

from __future__ import annotations

import base64
import html

from tml.report.figures import STATE_COLOURS, png
from tml.report.flight import Flight, Mark
from tml.report.scene import Scene, scene

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #212121; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.9em; }
th, td { border-bottom: 1px solid #e0e0e0; padding: 0.25em 0.8em; text-align: left; }
td.number { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; }
"""


def _cell(value: object, number: bool = False) -> str:
    text = "" if value is None else html.escape(str(value))
    return f'<td class="number">{text}</td>' if number else f"<td>{text}</td>"


def _seconds(value: float | None, start: float) -> str:
    return "" if value is None else f"{value - start:.1f}"


def _clock(wall: str) -> str:
    """The time of day of a ``wall`` field (``14:03:22.125``), "" when there is none."""
    return wall[11:23] if len(wall) >= 23 else ""


def _when(flight: Flight) -> str:
    """When the run was flown, by the wall clock, if the log says."""
    first, last = flight.walls
    if not first:
        return ""
    return (f"Flown {html.escape(first[:10])} from {html.escape(_clock(first))} to "
            f"{html.escape(_clock(last))} ({html.escape(first[23:] or 'local time')}).")


def _severity(mark: Mark) -> str:
    if not mark.severity:
        return ""
    said = f", said {mark.said}" if mark.said else ""
    return f" ({mark.severity}{said})"


def _counted(flight: Flight) -> str:
    """What the report's times count."""
    if flight.mission_start is None:
        return "The mission never started: times count from the start of the run."
    before = flight.mission_start - flight.start
    return (f"Times are mission time: seconds since the first task started, {before:.1f} s "
            "after the run did (earlier, negative).")


def _task_rows(drawn: Scene) -> str:
    rows = []
    for row in drawn.rows:
        duration = "" if row.end is None else f"{row.end - row.start:.1f}"
        colour = STATE_COLOURS.get(row.state, "#9e9e9e")
        what = f"event {row.event!r}: {row.task}" if row.event else row.task
        rows.append("<tr>" + _cell(what) + _cell(row.when) + _cell(row.vehicle, True)
                    + _cell(f"{row.start:.1f}", True)
                    + _cell("" if row.end is None else f"{row.end:.1f}", True)
                    + _cell(duration, True)
                    + f'<td style="color:{colour}">{html.escape(row.state)}</td></tr>')
    return "".join(rows)


def _spots(drawn: Scene) -> str:
    """The table of photos and detections, "" when there were none."""
    if not drawn.markers:
        return ""
    rows = "".join("<tr>" + _cell(f"{m.t:.1f}", True) + _cell(m.vehicle, True)
                   + _cell(m.kind) + _cell(m.text) + _cell(f"{m.north:.1f}", True)
                   + _cell(f"{m.east:.1f}", True) + "</tr>" for m in drawn.markers)
    frame = drawn.frame
    where = (f"metres from vehicle {frame.origin_vehicle}'s home, as on the map"
             if frame.shared else "metres from the vehicle's home")
    return (f"<h2>Photos and detections</h2>\n<p>Where each vehicle was ({where}).</p>\n"
            "<table><tr><th>mission time, s</th><th>vehicle</th><th>what</th><th>text</th>"
            f"<th>north (m)</th><th>east (m)</th></tr>\n{rows}</table>")


def page(flight: Flight) -> str:
    """The HTML text of the report."""
    drawn = scene(flight)
    image = base64.b64encode(png(flight, drawn=drawn)).decode("ascii")
    title = html.escape(flight.mission or flight.file)
    origin = flight.origin
    marks = ["<tr>" + _cell(_seconds(m.t, origin), True) + _cell(_clock(m.wall), True)
             + _cell(m.vehicle, True) + _cell(m.kind + _severity(m)) + _cell(m.text)
             + "</tr>" for m in flight.marks]
    outcomes = "".join(f"<li>vehicle {html.escape(str(o.get('vehicle')))}: "
                       f"<b>{html.escape(str(o.get('status')))}</b> "
                       f"({html.escape(str(o.get('reason')))})</li>"
                       for o in flight.outcomes) or f"<li>{html.escape(flight.outcome)}</li>"
    exit_code = "" if flight.exit_code is None else f"<p>Exit code {flight.exit_code}.</p>"
    unit = "mission time, s" if flight.mission_start is not None else "s"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Flight report: {title}</title>
<style>{STYLE}</style></head>
<body>
<h1>Flight report: {title}</h1>
<p>Mission file {html.escape(flight.mission_file or "unknown")}, flight log
{html.escape(flight.file)}; {flight.end - flight.start:.1f} s from the start of the run.
{_when(flight)} {_counted(flight)}</p>
<h2>Outcome</h2><ul>{outcomes}</ul>{exit_code}
<img alt="planned path and flown track, altitude, battery and task timeline"
 src="data:image/png;base64,{image}">
<h2>Tasks</h2>
<table><tr><th>task</th><th>round</th><th>vehicle</th><th>start ({unit})</th>
<th>end ({unit})</th><th>duration (s)</th><th>state</th></tr>
{_task_rows(drawn)}</table>
{_spots(drawn)}
<h2>Events, autopilot messages and safety steps</h2>
<table><tr><th>{unit}</th><th>wall clock</th><th>vehicle</th><th>what</th><th>text</th></tr>
{"".join(marks)}</table>
</body></html>
"""
