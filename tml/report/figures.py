"""The report's picture, drawn with matplotlib: where each vehicle flew against the plan,
altitude and battery over time, and the tasks on a timeline with the events, every time in
mission time (:attr:`~tml.report.flight.Flight.origin`), the tasks in tree order.

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

STATE_COLOURS = {"done": "#2e7d32", "failed": "#c62828", "aborted": "#8e2424",
                 "skipped": "#00838f", "running": "#f9a825"}
VEHICLE_COLOURS = ["#1565c0", "#ef6c00", "#6a1b9a", "#00897b", "#ad1457", "#5d4037",
                   "#283593", "#9e9d24"]
PLANNED_COLOURS = ["#bdbdbd", "#ffcc80", "#b39ddb", "#80cbc4"]
"""Pale, to lie under the tracks: one per role."""
WARNING_LEVELS = {"emergency", "alert", "critical", "error", "warning"}
TIMELINE_ROWS_SHOWN = 40
"""Task rows drawn at most; a longer mission shows its first ones and says how many more."""


def _colour(vehicle: int) -> str:
    return VEHICLE_COLOURS[(vehicle - 1) % len(VEHICLE_COLOURS)]


def _map(axes: Axes, flight: Flight) -> None:
    for corners in flight.obstacles:
        axes.fill([e for _, e in corners], [n for n, _ in corners], color="#ff9800",
                  alpha=0.35, linewidth=1, edgecolor="#e65100")
    if flight.obstacles:
        axes.fill([], [], color="#ff9800", alpha=0.35, label="obstacle")
    if flight.geofence:
        axes.plot([e for _, e in flight.geofence], [n for n, _ in flight.geofence],
                  color="#c62828", linestyle="--", linewidth=1.2, label="geofence")
    for (role, path), pale in zip(flight.planned.items(), itertools.cycle(PLANNED_COLOURS),
                                  strict=False):
        # Wide and pale under the tracks: where a vehicle flew as planned, both show.
        axes.plot([p[1] for p in path], [p[0] for p in path], color=pale,
                  linewidth=7, solid_capstyle="round", zorder=1,
                  label=f"planned{f' ({role})' if role else ''}")
        axes.plot([p[1] for p in path], [p[0] for p in path], color="#616161",
                  linestyle="none", marker="o", markersize=4, zorder=2)
    for vehicle, track in flight.tracks.items():
        colour = _colour(vehicle)
        axes.plot([s.east for s in track], [s.north for s in track], color=colour,
                  linewidth=2, label=f"vehicle {vehicle}", zorder=3)
        axes.plot(track[0].east, track[0].north, marker="^", color=colour, markersize=9)
        axes.plot(track[-1].east, track[-1].north, marker="s", color=colour, markersize=7)
    axes.set_title("Track: planned and flown (▲ start, ■ end)")
    axes.set_xlabel("east (m)")
    axes.set_ylabel("north (m)")
    axes.set_aspect("equal", adjustable="datalim")
    axes.grid(True, alpha=0.3)
    if axes.get_legend_handles_labels()[0]:  # a log without tracks has nothing to name
        axes.legend(loc="best", fontsize=8)


def _span(flight: Flight) -> tuple[float, float]:
    """The times the report's axes show: from the mission's start (or the first thing
    flown or sampled, if earlier) to the end of the log."""
    first = min([0.0, *(s.start - flight.origin for s in flight.tasks),
                 *(track[0].t - flight.origin for track in flight.tracks.values() if track)])
    last = max(flight.end - flight.origin, first + 1.0)
    pad = (last - first) * 0.01
    return first - pad, last + pad


def _over_time(axes: Axes, flight: Flight, what: str) -> None:
    for vehicle, track in flight.tracks.items():
        values = [(s.t - flight.origin, s.up if what == "altitude" else s.battery)
                  for s in track]
        shown = [(t, v) for t, v in values if v is not None]
        axes.plot([t for t, _ in shown], [v for _, v in shown], color=_colour(vehicle),
                  linewidth=1.8, label=f"vehicle {vehicle}")
    axes.set_title("Altitude above home" if what == "altitude" else "Battery")
    axes.set_ylabel("m" if what == "altitude" else "%")
    axes.set_xlabel(flight.time_label)
    axes.set_xlim(*_span(flight))
    axes.grid(True, alpha=0.3)
    if what == "battery":
        axes.set_ylim(bottom=0, top=105)
    if len(flight.tracks) > 1:
        axes.legend(loc="best", fontsize=8)


def _timeline(axes: Axes, flight: Flight) -> None:
    spans = flight.tasks[:TIMELINE_ROWS_SHOWN]
    several = len({s.vehicle for s in flight.tasks}) > 1
    labels = []
    for row, span in enumerate(spans):
        end = span.end if span.end is not None else flight.end
        width = max(end - span.start, (flight.end - flight.origin) / 400)
        axes.barh(row, width, left=span.start - flight.origin, height=0.7,
                  color=STATE_COLOURS.get(span.state, "#9e9e9e"))
        depth = span.task.count("/")
        name = span.task.rsplit("/", 1)[-1]
        who = f" [v{span.vehicle}]" if several and span.vehicle is not None else ""
        labels.append(f"{'· ' * depth}{name[:38]}{who}")
    axes.set_yticks(range(len(spans)), labels, fontsize=8)
    axes.set_ylim(max(len(spans), 1) - 0.5, -0.5)
    for mark in flight.marks:
        if mark.kind == "event":
            axes.axvline(mark.t - flight.origin, color="#ad1457", linewidth=1.2)
            axes.text(mark.t - flight.origin, -0.45, f" {mark.text}", color="#ad1457",
                      fontsize=8, va="top", rotation=0, clip_on=True)
        elif mark.kind == "autopilot" and mark.severity in WARNING_LEVELS:
            axes.axvline(mark.t - flight.origin, color="#c62828", linewidth=0.6,
                         linestyle=":")
    handles: list[Artist] = [Patch(color=colour, label=state)
                             for state, colour in STATE_COLOURS.items()
                             if any(s.state == state for s in spans)]
    handles.append(Line2D([], [], color="#ad1457", label="event"))
    handles.append(Line2D([], [], color="#c62828", linestyle=":", label="autopilot warning"))
    more = len(flight.tasks) - len(spans)
    axes.set_title("Tasks" + (f" (the first {len(spans)}; {more} more in the HTML report)"
                              if more > 0 else ""), loc="left")
    axes.set_xlabel(flight.time_label)
    axes.set_xlim(*_span(flight))
    axes.grid(True, axis="x", alpha=0.3)
    axes.legend(handles=handles, loc="lower right", bbox_to_anchor=(1.0, 1.0), fontsize=8,
                ncols=len(handles), frameon=False)


def figure(flight: Flight) -> Figure:
    """The report's figure for ``flight``."""
    rows = min(len(flight.tasks), TIMELINE_ROWS_SHOWN)
    timeline_height = 1.2 + 0.24 * max(rows, 3)
    fig = Figure(figsize=(13, 8 + timeline_height), layout="constrained")
    grid = fig.add_gridspec(3, 2, height_ratios=[4, 4, timeline_height * 1.25],
                            width_ratios=[1.15, 1])
    _map(fig.add_subplot(grid[0:2, 0]), flight)
    _over_time(fig.add_subplot(grid[0, 1]), flight, "altitude")
    _over_time(fig.add_subplot(grid[1, 1]), flight, "battery")
    _timeline(fig.add_subplot(grid[2, :]), flight)
    fig.suptitle(f"{flight.mission or flight.file} — {flight.outcome}", fontsize=13,
                 fontweight="bold")
    return fig


def png(flight: Flight, dpi: int = 100) -> bytes:
    """The figure as PNG bytes."""
    buffer = io.BytesIO()
    drawn = figure(flight)
    FigureCanvasAgg(drawn)
    drawn.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()
