"""What a report shows, in numbers: the data the picture (:mod:`tml.report.figures`) and the
page (:mod:`tml.report.pages`) are drawn from, so that what they show is tested on the data,
not on pixels.

*One frame for a fleet.* Every vehicle's telemetry gives its position from its own home;
the map draws them all in one frame, as the page of ``tml serve`` does: metres north and
east of the home of the vehicle with the lowest number whose home the log tells (a
position's ``global`` latitude and longitude, projected around that home). Each vehicle's
home is where its first positioned sample says it is; the planned path of each vehicle is
drawn from its own home, and the mission's obstacles and geofence at the home the mission
declares (else at the origin). A log written before positions carried ``global`` keeps
each vehicle in its own frame, and :attr:`Frame.shared` says so.

*Labels never overlap.* The events named on the timeline are laid out in lanes above the
tasks: a label goes to the first lane where it does not touch the one before it, or ends at
its event when it would run past the right edge; an event fired on several vehicles at the
same moment is one label that names them. The width of a label is estimated from its
characters at :data:`LABEL_POINTS` with :data:`CHAR_WIDTH` (wider than the font's average
character), against the narrowest the timeline can be; labels beyond :data:`LANES` lanes
are left out of the picture (the page's table lists every event) and the picture says how
many.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

from tml.geo import to_global, to_local
from tml.report.flight import Flight, Sample, TaskSpan

FIGURE_WIDTH = 13.0
"""Inches: the figure's width (at 100 dpi, 1300 pixels)."""
TIMELINE_ROWS_SHOWN = 40
"""Task rows drawn at most; a longer mission shows its first ones and says how many more."""
ROW_LABEL_CHARS = 44
"""A task's name on the timeline is cut to this many characters, less two a level down;
an event handler's row may take eight more, its action whole."""
LABEL_POINTS = 8.0
"""The size of the timeline's labels (points)."""
CHAR_WIDTH = 0.7
"""A character's width, in ems, reckoned for a label: more than DejaVu Sans' average, so
that an estimated label is never narrower than the one drawn."""
LANES = 3
"""Lanes of event labels above the timeline's tasks."""
TITLE_CHARS = 96
"""The title is wrapped to lines of at most this many characters (13 points, bold)."""


@dataclass(frozen=True)
class Frame:
    """The map's frame: metres north and east of ``origin`` (the home of vehicle
    ``origin_vehicle``: latitude, longitude, altitude AMSL), and each vehicle's home in it
    (north, east)."""

    origin_vehicle: int | None
    origin: tuple[float, float, float] | None
    homes: dict[int, tuple[float, float]]

    @property
    def shared(self) -> bool:
        """Whether the vehicles are in one frame (else each in its own, from its home)."""
        return self.origin is not None

    def offset(self, vehicle: int | None) -> tuple[float, float]:
        """Where a vehicle's home is in the frame ((0, 0) when unknown)."""
        return self.homes.get(vehicle, (0.0, 0.0)) if vehicle is not None else (0.0, 0.0)

    def place(self, vehicle: int, sample: Sample) -> tuple[float, float]:
        """Where a sample of a vehicle is in the frame (north, east)."""
        if self.origin is not None and sample.latitude is not None \
                and sample.longitude is not None:
            north, east, _ = to_local(sample.latitude, sample.longitude,
                                      sample.altitude or self.origin[2], *self.origin)
            return north, east
        dn, de = self.offset(vehicle)
        return sample.north + dn, sample.east + de


@dataclass(frozen=True)
class Line:
    """A path on the map: a vehicle's flown track, or a planned path (of ``role``, drawn
    from ``vehicle``'s home; vehicle None: from the origin)."""

    vehicle: int | None
    role: str
    points: tuple[tuple[float, float], ...]  # (north, east) in the frame


@dataclass(frozen=True)
class Marker:
    """A photo or a detection on the map, where the vehicle was at ``t`` (mission time)."""

    kind: str  # "photo", "detection"
    vehicle: int
    t: float
    north: float
    east: float
    text: str


@dataclass(frozen=True)
class Row:
    """A row of the timeline and of the page's table of tasks: a task as it ran on a
    vehicle, or an event handler's action (``event`` names the event); times in mission
    time."""

    label: str  # as the timeline names it: indented by depth, the round, the vehicle
    task: str  # the task's path, or the action of an event handler
    vehicle: int | None
    start: float
    end: float | None  # None: it still ran when the log ended
    state: str
    event: str = ""
    round: int = 0
    rounds: int | None = None

    @property
    def when(self) -> str:
        """Which round it was, as the page says it ("" for the first and only)."""
        if not self.round:
            return ""
        return f"round {self.round}" + (f" of {self.rounds}" if self.rounds else "")


@dataclass(frozen=True)
class Label:
    """An event's name on the timeline: drawn from ``x`` (mission time) to the right, or,
    with ``right`` set, ending at ``x``; ``box`` is the room it takes, (left, right) in
    seconds and (top, bottom) in lanes, ``lane`` 0 being next to the tasks."""

    text: str
    t: float
    lane: int
    right: bool
    box: tuple[float, float, float, float]  # (x0, x1, y0, y1)


@dataclass(frozen=True)
class Scene:
    """Everything the picture and the page draw."""

    title: tuple[str, ...]
    vehicles: tuple[int, ...]  # by number
    frame: Frame
    tracks: tuple[Line, ...]  # by vehicle number
    planned: tuple[Line, ...]
    obstacles: tuple[tuple[tuple[float, float], ...], ...]  # (north, east) in the frame
    geofence: tuple[tuple[float, float], ...]
    markers: tuple[Marker, ...]
    rows: tuple[Row, ...]  # every task span, in tree order
    span: tuple[float, float]  # the times the axes show (mission time)
    labels: tuple[Label, ...]
    labels_left_out: int

    @property
    def shown_rows(self) -> tuple[Row, ...]:
        """The rows the timeline draws."""
        return self.rows[:TIMELINE_ROWS_SHOWN]


def frame_of(flight: Flight) -> Frame:
    """The shared frame of the flight's vehicles (see the module's docstring)."""
    homes: dict[int, tuple[float, float, float]] = {}
    for vehicle in flight.vehicles:
        sample = next((s for s in flight.tracks[vehicle] if s.latitude is not None
                       and s.longitude is not None and s.altitude is not None), None)
        if sample is not None:
            assert sample.latitude is not None and sample.longitude is not None
            assert sample.altitude is not None
            homes[vehicle] = to_global(-sample.north, -sample.east, -sample.up,
                                       sample.latitude, sample.longitude, sample.altitude)
    if not homes:
        return Frame(None, None, {})
    first = min(homes)
    origin = homes[first]
    return Frame(first, origin, {v: _north_east(home, origin) for v, home in homes.items()})


def _north_east(where: tuple[float, float, float],
                origin: tuple[float, float, float]) -> tuple[float, float]:
    north, east, _ = to_local(*where, *origin)
    return north, east


def _at(track: list[Sample], t: float) -> Sample:
    """The sample of a track at ``t``: the last one by then, else the first."""
    found = track[0]
    for sample in track:
        if sample.t > t:
            break
        found = sample
    return found


def _planned(flight: Flight, frame: Frame) -> tuple[Line, ...]:
    """Each role's planned path from the home of each vehicle that flew it (a mission
    without roles: every vehicle), as the page draws them; a role no vehicle flew, from the
    origin."""
    lines: list[Line] = []
    for role, path in flight.planned.items():
        vehicles: list[int | None] = list(
            sorted(flight.picked.get(role, [])) if role else flight.vehicles) or [None]
        for vehicle in vehicles:
            dn, de = frame.offset(vehicle)
            lines.append(Line(vehicle, role, tuple((n + dn, e + de) for n, e, _ in path)))
    return tuple(lines)


def _label(span: TaskSpan, several: bool) -> str:
    """How the timeline names a row."""
    who = f" [v{span.vehicle}]" if several and span.vehicle is not None else ""
    if span.event:  # the action whole, the event's name cut to make room
        room = max(ROW_LABEL_CHARS + 8 - len(span.task) - len("event '': "), 4)
        name = span.event if len(span.event) <= room else span.event[:room - 1] + "…"
        return f"event '{name}': {span.task}{who}"
    depth = span.task.count("/")
    name = span.task.rsplit("/", 1)[-1]
    when = f" (round {span.round})" if span.round else ""
    return f"{'· ' * depth}{name[:ROW_LABEL_CHARS - 2 * depth]}{when}{who}"


def _rows(flight: Flight) -> tuple[Row, ...]:
    several = len({s.vehicle for s in flight.tasks if s.vehicle is not None}) > 1
    origin = flight.origin
    return tuple(Row(_label(span, several), span.task, span.vehicle, span.start - origin,
                     None if span.end is None else span.end - origin, span.state,
                     span.event, span.round, span.rounds) for span in flight.tasks)


def _span(flight: Flight) -> tuple[float, float]:
    """The times the report's axes show: from the mission's start (or the first thing
    flown or sampled, if earlier) to the end of the log."""
    first = min([0.0, *(s.start - flight.origin for s in flight.tasks),
                 *(track[0].t - flight.origin for track in flight.tracks.values() if track)])
    last = max(flight.end - flight.origin, first + 1.0)
    pad = (last - first) * 0.01
    return first - pad, last + pad


def timeline_inches(rows: tuple[Row, ...]) -> float:
    """The narrowest the timeline can be (inches): the figure less the row labels beside
    it (at their estimated widths) and the margins."""
    widest = max((len(r.label) for r in rows[:TIMELINE_ROWS_SHOWN]), default=0)
    return FIGURE_WIDTH - widest * CHAR_WIDTH * LABEL_POINTS / 72 - 0.9


def _labels(flight: Flight, rows: tuple[Row, ...],
            span: tuple[float, float]) -> tuple[tuple[Label, ...], int]:
    """The events' labels laid out in lanes (see the module's docstring), and how many
    were left out."""
    fired: dict[tuple[str, float], list[int | None]] = {}
    for mark in flight.marks:
        if mark.kind == "event":
            fired.setdefault((mark.text, round(mark.t - flight.origin, 1)), []).append(
                mark.vehicle)
    per_second = timeline_inches(rows) / (span[1] - span[0])  # inches a second
    ends: list[float] = []  # the right edge of the last label of each lane
    placed: list[Label] = []
    left_out = 0
    for (text, t), vehicles in sorted(fired.items(), key=lambda item: item[0][1]):
        numbers = sorted({v for v in vehicles if v is not None})
        if len(numbers) > 1:
            text = f"{text} (vehicles {', '.join(map(str, numbers))})"
        width = (len(text) + 1) * CHAR_WIDTH * LABEL_POINTS / 72 / per_second
        right = t + width > span[1]
        x0, x1 = (t - width, t) if right else (t, t + width)
        lane = next((i for i, end in enumerate(ends) if end < x0), len(ends))
        if lane >= LANES:
            left_out += 1
            continue
        if lane == len(ends):
            ends.append(x1)
        ends[lane] = x1
        placed.append(Label(text, t, lane, right, (x0, x1, float(lane), lane + 1.0)))
    return tuple(placed), left_out


def _title(flight: Flight) -> tuple[str, ...]:
    said = f"{flight.mission or flight.file} — {flight.outcome}"
    return tuple(textwrap.wrap(said, TITLE_CHARS, break_on_hyphens=False)) or ("",)


def scene(flight: Flight) -> Scene:
    """What the report of ``flight`` shows."""
    frame = frame_of(flight)
    tracks = tuple(Line(v, "", tuple(frame.place(v, s) for s in flight.tracks[v]))
                   for v in flight.vehicles)
    dn, de = _north_east(flight.world_home, frame.origin) \
        if flight.world_home is not None and frame.origin is not None else (0.0, 0.0)
    markers = tuple(Marker(spot.kind, spot.vehicle, spot.t - flight.origin,
                           *frame.place(spot.vehicle, _at(flight.tracks[spot.vehicle], spot.t)),
                           spot.text)
                    for spot in flight.spots if flight.tracks.get(spot.vehicle))
    rows = _rows(flight)
    span = _span(flight)
    labels, left_out = _labels(flight, rows, span)
    return Scene(
        _title(flight), tuple(flight.vehicles), frame, tracks, _planned(flight, frame),
        tuple(tuple((n + dn, e + de) for n, e in corners) for corners in flight.obstacles),
        tuple((n + dn, e + de) for n, e in flight.geofence), markers, rows, span, labels,
        left_out)
