"""The report's picture, drawn with matplotlib from the report's data
(:class:`~tml.report.scene.Scene`): where each vehicle flew against the plan, in one frame
for the fleet, with its photos and detections; altitude and battery over time; and the
tasks and the event handlers' actions on a timeline, with the events named above them
(never on top of each other), every time in mission time
(:attr:`~tml.report.flight.Flight.origin`), the tasks in tree order, vehicles by number.

The figure is made without pyplot (a :class:`~matplotlib.figure.Figure` on the Agg canvas),
so nothing opens a window or keeps global state, and it draws the same on a machine with
no display.
"""

from __future__ import annotations

import io
import itertools

from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from tml.report.flight import Flight
from tml.report.scene import FIGURE_WIDTH, LABEL_POINTS, TIMELINE_ROWS_SHOWN, Scene, scene

STATE_COLOURS = {"done": "#2e7d32", "failed": "#c62828", "aborted": "#8e2424",
                 "skipped": "#00838f", "running": "#f9a825"}
VEHICLE_COLOURS = ["#1565c0", "#ef6c00", "#6a1b9a", "#00897b", "#ad1457", "#5d4037",
                   "#283593", "#9e9d24"]
PLANNED_COLOURS = ["#bdbdbd", "#ffcc80", "#b39ddb", "#80cbc4"]
"""Pale, to lie under the tracks: one per role."""
WARNING_LEVELS = {"emergency", "alert", "critical", "error", "warning"}
EVENT_COLOUR = "#ad1457"
MARKERS = {"photo": ("P", "#37474f", "photo"), "detection": ("*", "#d81b60", "detection")}
"""How the map marks a photo and a detection: marker, colour, legend."""


def _colour(vehicle: int) -> str:
    return VEHICLE_COLOURS[(vehicle - 1) % len(VEHICLE_COLOURS)]


def _width(order: int, lines: int, narrowest: float = 1.6, step: float = 1.4) -> float:
    """The width of the line of the ``order``-th of ``lines`` vehicles. Vehicles that fly
    the same ground (a relay's sorties), or the same altitudes and charges, would hide each
    other: the later a vehicle is drawn the narrower its line, so that each earlier one
    borders it (on the map, the first of four 5.8 points wide, the last 1.6)."""
    return narrowest + step * (min(lines, 4) - 1 - min(order, 3))


def _map(axes: Axes, drawn: Scene) -> None:
    for corners in drawn.obstacles:
        axes.fill([e for _, e in corners], [n for n, _ in corners], color="#ff9800",
                  alpha=0.35, linewidth=1, edgecolor="#e65100")
    if drawn.obstacles:
        axes.fill([], [], color="#ff9800", alpha=0.35, label="obstacle")
    if drawn.geofence:
        axes.plot([e for _, e in drawn.geofence], [n for n, _ in drawn.geofence],
                  color="#c62828", linestyle="--", linewidth=1.2, label="geofence")
    pales = dict(zip(dict.fromkeys(line.role for line in drawn.planned),
                     itertools.cycle(PLANNED_COLOURS), strict=False))
    named: set[str] = set()
    for line in drawn.planned:
        # Wide and pale under the tracks: where a vehicle flew as planned, both show.
        label = f"planned{f' ({line.role})' if line.role else ''}"
        axes.plot([e for _, e in line.points], [n for n, _ in line.points],
                  color=pales[line.role], linewidth=7, solid_capstyle="round", zorder=1,
                  label=None if label in named else label)
        named.add(label)
        axes.plot([e for _, e in line.points], [n for n, _ in line.points], color="#616161",
                  linestyle="none", marker="o", markersize=4, zorder=2)
    for order, track in enumerate(drawn.tracks):
        if not track.points or track.vehicle is None:
            continue
        colour = _colour(track.vehicle)
        axes.plot([e for _, e in track.points], [n for n, _ in track.points], color=colour,
                  linewidth=_width(order, len(drawn.tracks)),
                  label=f"vehicle {track.vehicle}", zorder=3, solid_capstyle="round")
        axes.plot(track.points[0][1], track.points[0][0], marker="^", color=colour,
                  markersize=9, zorder=4)
        axes.plot(track.points[-1][1], track.points[-1][0], marker="s", color=colour,
                  markersize=7, zorder=4)
    for kind, (marker, colour, label) in MARKERS.items():
        found = [m for m in drawn.markers if m.kind == kind]
        if found:
            axes.plot([m.east for m in found], [m.north for m in found], linestyle="none",
                      marker=marker, color=colour, markersize=9, markeredgecolor="white",
                      label=f"{label} ({len(found)})", zorder=5)
    frame = drawn.frame
    where = (f"m from vehicle {frame.origin_vehicle}'s home" if frame.shared and
             len(drawn.vehicles) > 1 else "m from home" if frame.shared
             else "m from each vehicle's own home")
    axes.set_title("Track: planned and flown (▲ start, ■ end)")
    axes.set_xlabel(f"east ({where})")
    axes.set_ylabel("north (m)")
    axes.set_aspect("equal", adjustable="datalim")
    axes.grid(True, alpha=0.3)
    if axes.get_legend_handles_labels()[0]:  # a log without tracks has nothing to name
        axes.legend(loc="best", fontsize=8)


def _over_time(axes: Axes, flight: Flight, drawn: Scene, what: str) -> None:
    for order, vehicle in enumerate(drawn.vehicles):
        values = [(s.t - flight.origin, s.up if what == "altitude" else s.battery)
                  for s in flight.tracks[vehicle]]
        shown = [(t, v) for t, v in values if v is not None]
        axes.plot([t for t, _ in shown], [v for _, v in shown], color=_colour(vehicle),
                  linewidth=_width(order, len(drawn.vehicles), 1.2, 0.8),
                  label=f"vehicle {vehicle}")
    axes.set_title("Altitude above home" if what == "altitude" else "Battery")
    axes.set_ylabel("m" if what == "altitude" else "%")
    axes.set_xlabel(flight.time_label)
    axes.set_xlim(*drawn.span)
    axes.grid(True, alpha=0.3)
    if what == "battery":
        axes.set_ylim(bottom=0, top=105)
    if len(drawn.vehicles) > 1:
        axes.legend(loc="best", fontsize=8)


def _timeline(axes: Axes, flight: Flight, drawn: Scene) -> None:
    rows = drawn.shown_rows
    end_of_log = flight.end - flight.origin
    for number, row in enumerate(rows):
        end = row.end if row.end is not None else end_of_log
        width = max(end - row.start, (end_of_log - drawn.span[0]) / 400)
        axes.barh(number, width, left=row.start, height=0.7,
                  color=STATE_COLOURS.get(row.state, "#9e9e9e"),
                  hatch="///" if row.event else None, edgecolor="white" if row.event
                  else None, linewidth=0)
    axes.set_yticks(range(len(rows)), [row.label for row in rows], fontsize=LABEL_POINTS)
    lanes = max((label.lane + 1 for label in drawn.labels), default=0)
    # The labels' lanes lie above the first row: a lane is a row high.
    axes.set_ylim(max(len(rows), 1) - 0.5, -0.5 - lanes)
    for mark in flight.marks:
        if mark.kind == "event":
            axes.axvline(mark.t - flight.origin, color=EVENT_COLOUR, linewidth=1.2)
        elif mark.kind == "autopilot" and mark.severity in WARNING_LEVELS:
            axes.axvline(mark.t - flight.origin, color="#c62828", linewidth=0.6,
                         linestyle=":")
    for label in drawn.labels:
        axes.text(label.t, -0.5 - label.lane - 0.5, f" {label.text} " if label.right
                  else f" {label.text}", color=EVENT_COLOUR, fontsize=LABEL_POINTS,
                  va="center", ha="right" if label.right else "left", clip_on=False,
                  gid="event label", zorder=6,
                  bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.3})
    handles: list[Artist] = [Patch(color=colour, label=state)
                             for state, colour in STATE_COLOURS.items()
                             if any(r.state == state for r in rows)]
    if any(r.event for r in rows):
        handles.append(Patch(facecolor="#9e9e9e", hatch="///", edgecolor="white",
                             label="event handler's action"))
    handles.append(Line2D([], [], color=EVENT_COLOUR, label="event"))
    handles.append(Line2D([], [], color="#c62828", linestyle=":", label="autopilot warning"))
    more = len(drawn.rows) - len(rows)
    title = "Tasks" + (f" (the first {len(rows)}; {more} more in the HTML report)"
                       if more > 0 else "")
    if drawn.labels_left_out:
        title += f"; {drawn.labels_left_out} event label(s) left out"
    axes.set_title(title, loc="left")
    axes.set_xlabel(flight.time_label)
    axes.set_xlim(*drawn.span)
    axes.grid(True, axis="x", alpha=0.3)
    axes.legend(handles=handles, loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=8,
                ncols=len(handles), frameon=False)


def figure(flight: Flight, drawn: Scene | None = None) -> Figure:
    """The report's figure for ``flight`` (its data: ``drawn``, else :func:`scene`)."""
    drawn = drawn or scene(flight)
    rows = min(len(drawn.rows), TIMELINE_ROWS_SHOWN)
    lanes = max((label.lane + 1 for label in drawn.labels), default=0)
    timeline_height = 1.6 + 0.24 * (max(rows, 3) + lanes)
    title_height = 0.25 * len(drawn.title)
    fig = Figure(figsize=(FIGURE_WIDTH, 8 + timeline_height + title_height),
                 layout="constrained")
    grid = fig.add_gridspec(3, 2, height_ratios=[4, 4, timeline_height * 1.25],
                            width_ratios=[1.15, 1])
    _map(fig.add_subplot(grid[0:2, 0]), drawn)
    _over_time(fig.add_subplot(grid[0, 1]), flight, drawn, "altitude")
    _over_time(fig.add_subplot(grid[1, 1]), flight, drawn, "battery")
    _timeline(fig.add_subplot(grid[2, :]), flight, drawn)
    fig.suptitle("\n".join(drawn.title), fontsize=13, fontweight="bold")
    return fig


def png(flight: Flight, dpi: int = 100, drawn: Scene | None = None) -> bytes:
    """The figure as PNG bytes, in a palette of 256 colours (a picture of lines and bars
    has fewer, and anti-aliasing loses nothing to see): a third of the size of the full
    colours, so that a page that embeds it can be mailed."""
    from PIL import Image  # matplotlib's own dependency

    buffer = io.BytesIO()
    made = figure(flight, drawn)
    FigureCanvasAgg(made)
    made.savefig(buffer, format="png", dpi=dpi)
    picture = Image.open(io.BytesIO(buffer.getvalue())).convert("RGB")
    buffer = io.BytesIO()
    picture.quantize(256, Image.Quantize.MEDIANCUT).save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()
