"""The flown tracks for map tools: GPX 1.1 (a track per vehicle, a point per telemetry line,
with its elevation AMSL and time) and KML 2.2 (a line per vehicle, altitudes absolute).

Times in GPX are UTC instants. A track's first point is stamped with the wall-clock time of
its line (the log's ``wall``), and the others follow it on the log's own clock ``t`` (the
simulator's vehicle time with ``--sim``): the date is when it flew, and the intervals are
the vehicle's, so that the speeds a map tool computes are right even for a simulator run
faster than real time. A log written without ``wall`` is stamped from the Unix epoch on
(1970-01-01T00:00:00Z plus the log's seconds): the intervals are right, the dates are not
a claim of when it flew. Telemetry lines without a position on the globe (a log written
before the vehicle's home was known) are left out.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from lxml import etree

from tml.plans.maps import KML_NAMESPACE
from tml.report.flight import Flight, Sample

GPX_NAMESPACE = "http://www.topografix.com/GPX/1/1"


def _placed(track: list[Sample]) -> list[Sample]:
    return [s for s in track if s.latitude is not None and s.longitude is not None]


def _anchor(sample: Sample) -> datetime | None:
    """The UTC instant of a sample's wall-clock time, None when its line has none."""
    try:
        moment = datetime.fromisoformat(sample.wall) if sample.wall else None
    except ValueError:
        return None
    if moment is None or moment.tzinfo is None:
        return None
    return moment.astimezone(UTC)


def gpx(flight: Flight) -> str:
    """The GPX text of the flight's tracks."""
    g = f"{{{GPX_NAMESPACE}}}"
    root = etree.Element(f"{g}gpx", nsmap={None: GPX_NAMESPACE}, version="1.1", creator="tml")
    metadata = etree.SubElement(root, f"{g}metadata")
    etree.SubElement(metadata, f"{g}name").text = flight.mission or flight.file
    for vehicle, track in sorted(flight.tracks.items()):
        element = etree.SubElement(root, f"{g}trk")
        etree.SubElement(element, f"{g}name").text = f"vehicle {vehicle}"
        segment = etree.SubElement(element, f"{g}trkseg")
        placed = _placed(track)
        anchor = _anchor(placed[0]) if placed else None
        for sample in placed:
            point = etree.SubElement(segment, f"{g}trkpt", lat=f"{sample.latitude:.7f}",
                                     lon=f"{sample.longitude:.7f}")
            if sample.altitude is not None:
                etree.SubElement(point, f"{g}ele").text = f"{sample.altitude:.2f}"
            instant = datetime.fromtimestamp(sample.t, UTC) if anchor is None \
                else anchor + timedelta(seconds=sample.t - placed[0].t)
            etree.SubElement(point, f"{g}time").text = instant.isoformat(
                timespec="milliseconds").replace("+00:00", "Z")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8",
                          pretty_print=True).decode("utf-8")


def kml(flight: Flight) -> str:
    """The KML text of the flight's tracks."""
    k = f"{{{KML_NAMESPACE}}}"
    root = etree.Element(f"{k}kml", nsmap={None: KML_NAMESPACE})
    document = etree.SubElement(root, f"{k}Document")
    etree.SubElement(document, f"{k}name").text = flight.mission or flight.file
    for vehicle, track in sorted(flight.tracks.items()):
        mark = etree.SubElement(document, f"{k}Placemark")
        etree.SubElement(mark, f"{k}name").text = f"vehicle {vehicle}"
        line = etree.SubElement(mark, f"{k}LineString")
        etree.SubElement(line, f"{k}altitudeMode").text = "absolute"
        etree.SubElement(line, f"{k}coordinates").text = " ".join(
            f"{s.longitude:.7f},{s.latitude:.7f},{s.altitude or 0.0:.2f}"
            for s in _placed(track))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8",
                          pretty_print=True).decode("utf-8")
