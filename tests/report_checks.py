"""Checks of a report's picture and data that the report tests share."""

from __future__ import annotations

import itertools

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tml.report.scene import Scene


def texts_fit(drawn: Figure) -> None:
    """All that is drawn lies inside the figure (the title, the row labels, the event
    labels: nothing is cut), and the event labels overlap nothing of their own kind (as
    drawn: the renderer's boxes)."""
    canvas = FigureCanvasAgg(drawn)
    canvas.draw()
    renderer = canvas.get_renderer()
    drawn_at = drawn.get_tightbbox(renderer)  # inches
    width, height = drawn.get_size_inches()
    assert drawn_at.x0 >= -0.01 and drawn_at.y0 >= -0.01, drawn_at
    assert drawn_at.x1 <= width + 0.01 and drawn_at.y1 <= height + 0.01, drawn_at
    labels = [t.get_window_extent(renderer) for t in drawn.findobj(
        lambda a: getattr(a, "get_gid", lambda: None)() == "event label")]
    for a, b in itertools.combinations(labels, 2):
        assert not a.overlaps(b)
    inside = drawn.axes[-1].bbox  # the timeline's
    for box in labels:
        assert inside.x0 - 1 <= box.x0 and box.x1 <= inside.x1 + 1


def boxes_apart(drawn: Scene) -> None:
    """The labels' boxes of the report's data intersect nowhere."""
    for a, b in itertools.combinations(drawn.labels, 2):
        assert a.box[1] <= b.box[0] or b.box[1] <= a.box[0] or a.lane != b.lane, (a, b)
