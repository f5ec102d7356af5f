"""The report as one HTML page: the figure embedded, the outcome, and tables of the tasks and
of what happened (events, autopilot messages, safety steps), with nothing fetched from
anywhere: the page opens offline and can be mailed as it is."""

from __future__ import annotations

import base64
import html

from tml.report.figures import STATE_COLOURS, png
from tml.report.flight import Flight

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


def page(flight: Flight) -> str:
    """The HTML text of the report."""
    image = base64.b64encode(png(flight)).decode("ascii")
    title = html.escape(flight.mission or flight.file)
    rows = []
    for span in flight.tasks:
        end = span.end
        duration = "" if end is None else f"{end - span.start:.1f}"
        colour = STATE_COLOURS.get(span.state, "#9e9e9e")
        rows.append("<tr>" + _cell(span.task) + _cell(span.vehicle, True)
                    + _cell(_seconds(span.start, flight.start), True)
                    + _cell(_seconds(end, flight.start), True) + _cell(duration, True)
                    + f'<td style="color:{colour}">{html.escape(span.state)}</td></tr>')
    marks = ["<tr>" + _cell(_seconds(m.t, flight.start), True) + _cell(m.vehicle, True)
             + _cell(m.kind + (f" ({m.severity})" if m.severity else "")) + _cell(m.text)
             + "</tr>" for m in flight.marks]
    outcomes = "".join(f"<li>vehicle {html.escape(str(o.get('vehicle')))}: "
                       f"<b>{html.escape(str(o.get('status')))}</b> "
                       f"({html.escape(str(o.get('reason')))})</li>"
                       for o in flight.outcomes) or f"<li>{html.escape(flight.outcome)}</li>"
    exit_code = "" if flight.exit_code is None else f"<p>Exit code {flight.exit_code}.</p>"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Flight report: {title}</title>
<style>{STYLE}</style></head>
<body>
<h1>Flight report: {title}</h1>
<p>Mission file {html.escape(flight.mission_file or "unknown")}, flight log
{html.escape(flight.file)}; {flight.end - flight.start:.1f} s from the start of the run.</p>
<h2>Outcome</h2><ul>{outcomes}</ul>{exit_code}
<img alt="planned path and flown track, altitude, battery and task timeline"
 src="data:image/png;base64,{image}">
<h2>Tasks</h2>
<table><tr><th>task</th><th>vehicle</th><th>start (s)</th><th>end (s)</th>
<th>duration (s)</th><th>state</th></tr>
{"".join(rows)}</table>
<h2>Events, autopilot messages and safety steps</h2>
<table><tr><th>time (s)</th><th>vehicle</th><th>what</th><th>text</th></tr>
{"".join(marks)}</table>
</body></html>
"""
