// The map of the page: an SVG drawing in one shared frame (metres north and east of one
// origin, the first vehicle's home), north up, on a grid with a scale bar and a north
// arrow; or the same over map tiles (below: drawSceneMap). It is drawn from a scene, every
// point already in that frame:
//   {world: {geofence, obstacles},
//    plans: [{key, vehicle, points: [[n, e, u], ...]}],   vehicle null: not yet picked
//    tracks: [{vehicle, points: [[n, e], ...]}],
//    homes: [{vehicle, point: [n, e]}],
//    vehicles: [{id, position: [n, e, u], heading, faded}],
//    place: ([n, e]) -> [latitude, longitude], or null while no origin is known}
// Each vehicle has its own colour (vehicleColour), used for its marker, its home, its
// planned path (dashed) and its track (solid), and in the legend the page draws.
// SVG x is east and y is minus north, so that north is up.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const INK = "#1d2430";
const UNPICKED = "#6e7781";  // the plan of a role no vehicle flies yet

function svgElement(name, attributes, text) {
  const element = document.createElementNS(SVG, name);
  for (const [key, value] of Object.entries(attributes || {})) {
    element.setAttribute(key, String(value));
  }
  if (text !== undefined) element.textContent = text;
  return element;
}

// Colour-blind-safe colours (Okabe and Ito), none of them the red of a failed task.
const PALETTE = ["#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#000000"];

function vehicleColour(id) {
  return PALETTE[((Number(id) - 1) % PALETTE.length + PALETTE.length) % PALETTE.length];
}

// The two line styles of the map, shared with the legend: the track flown is a wide pale
// band, the planned path a thin dashed line drawn over it, so that both show where the
// vehicle flew as planned.
const PLANNED = {"stroke-width": 1.5, "stroke-dasharray": "6 4"};
const FLOWN = {"stroke-width": 5, "stroke-opacity": 0.45, "stroke-linecap": "round",
  "stroke-linejoin": "round"};

// A length of 1, 2 or 5 times a power of ten near `about`.
function niceLength(about) {
  const power = Math.pow(10, Math.floor(Math.log10(Math.max(about, 1e-6))));
  for (const step of [1, 2, 5, 10]) {
    if (step * power >= about) return step * power;
  }
  return 10 * power;
}

function sceneBounds(scene) {
  const points = [[0, 0]];
  const world = scene.world || {};
  if (world.geofence && world.geofence.polygon) points.push(...world.geofence.polygon);
  for (const obstacle of world.obstacles || []) {
    if (obstacle.shape === "cylinder") {
      points.push([obstacle.north - obstacle.radius, obstacle.east - obstacle.radius],
                  [obstacle.north + obstacle.radius, obstacle.east + obstacle.radius]);
    } else {
      points.push(...obstacle.polygon);
    }
  }
  for (const plan of scene.plans || []) points.push(...plan.points);
  for (const track of scene.tracks || []) points.push(...track.points);
  for (const home of scene.homes || []) points.push(home.point);
  for (const vehicle of scene.vehicles || []) {
    if (vehicle.position) points.push(vehicle.position);
  }
  let [minN, maxN, minE, maxE] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const [n, e] of points) {
    minN = Math.min(minN, n); maxN = Math.max(maxN, n);
    minE = Math.min(minE, e); maxE = Math.max(maxE, e);
  }
  const span = Math.max(maxN - minN, maxE - minE, 20) * 1.2;
  const [midN, midE] = [(minN + maxN) / 2, (minE + maxE) / 2];
  return {x: midE - span / 2, y: -midN - span / 2, span: span};
}

function pathOf(points) {
  return points.map(([n, e], i) => `${i ? "L" : "M"}${e.toFixed(2)},${(-n).toFixed(2)}`).join(" ");
}

function drawMap(svg, scene) {
  const box = sceneBounds(scene);
  const unit = box.span / 100;  // one hundredth of the view, for sizes of marks and text
  svg.setAttribute("viewBox", `${box.x} ${box.y} ${box.span} ${box.span}`);
  svg.replaceChildren();
  const world = scene.world || {};
  const line = {"vector-effect": "non-scaling-stroke", fill: "none"};

  // The grid, one line every scale-bar length, through the origin.
  const length = niceLength(box.span / 5);
  const steps = (from) => {
    const found = [];
    for (let at = Math.ceil(from / length) * length; at <= from + box.span; at += length) {
      found.push(at);
    }
    return found;
  };
  const grid = [...steps(box.x).map((x) => `M${x},${box.y} V${box.y + box.span}`),
    ...steps(box.y).map((y) => `M${box.x},${y} H${box.x + box.span}`)];
  svg.append(svgElement("path", {...line, class: "grid", stroke: "#d8dee4", "stroke-width": 1,
    d: grid.join(" ")}));

  const fence = world.geofence;
  if (fence && fence.polygon && fence.polygon.length) {
    svg.append(svgElement("path", {...line, class: "geofence", stroke: "#9a6700",
      "stroke-width": 2, d: pathOf(fence.polygon) + " Z"}));
  }
  for (const obstacle of world.obstacles || []) {
    const look = {class: "obstacle", fill: "#8c959f", "fill-opacity": 0.6, stroke: "#57606a",
      "vector-effect": "non-scaling-stroke"};
    const shape = obstacle.shape === "cylinder"
      ? svgElement("circle", {...look, cx: obstacle.east, cy: -obstacle.north, r: obstacle.radius})
      : svgElement("path", {...look, d: pathOf(obstacle.polygon) + " Z"});
    shape.append(svgElement("title", {}, obstacle.name));
    svg.append(shape);
  }
  for (const home of scene.homes || []) {
    const [n, e] = home.point;
    const mark = svgElement("circle", {class: "home", "data-vehicle": home.vehicle,
      "data-north": n.toFixed(2), "data-east": e.toFixed(2), cx: e, cy: -n, r: unit * 1.2,
      fill: "white", stroke: vehicleColour(home.vehicle), "stroke-width": 2,
      "vector-effect": "non-scaling-stroke"});
    mark.append(svgElement("title", {}, `vehicle ${home.vehicle}: home`));
    svg.append(mark);
  }

  for (const track of scene.tracks || []) {
    if (track.points.length > 1) {
      svg.append(svgElement("path", {...line, ...FLOWN, class: "track",
        "data-vehicle": track.vehicle, stroke: vehicleColour(track.vehicle),
        d: pathOf(track.points)}));
    }
  }
  for (const plan of scene.plans || []) {
    if (plan.points.length > 1) {
      const colour = plan.vehicle === null ? UNPICKED : vehicleColour(plan.vehicle);
      const path = svgElement("path", {...line, ...PLANNED, class: "plan", "data-plan": plan.key,
        stroke: colour, d: pathOf(plan.points)});
      if (plan.vehicle !== null) path.setAttribute("data-vehicle", plan.vehicle);
      svg.append(path);
    }
  }
  for (const vehicle of scene.vehicles || []) {
    if (!vehicle.position) continue;
    const [n, e, u] = vehicle.position;
    const marker = svgElement("g", {class: "vehicle", "data-vehicle": vehicle.id,
      "data-north": n.toFixed(2), "data-east": e.toFixed(2), "data-up": u.toFixed(2),
      transform: `translate(${e} ${-n}) rotate(${vehicle.heading || 0})`,
      opacity: vehicle.faded ? 0.45 : 1});
    const size = unit * 2.5;
    marker.append(svgElement("path", {d: `M0,${-size} L${size * 0.7},${size} L0,${size * 0.5} ` +
      `L${-size * 0.7},${size} Z`, fill: vehicleColour(vehicle.id), stroke: "white",
      "vector-effect": "non-scaling-stroke"}));
    marker.append(svgElement("title", {}, `vehicle ${vehicle.id}: ${u.toFixed(1)} m up`));
    svg.append(marker);
    // Odd ids are labelled left of their marker, even ones right: vehicles side by side
    // (a fleet boots in a row, 1 west of 2) keep their labels apart.
    const right = Number(vehicle.id) % 2 === 0;
    svg.append(svgElement("text", {class: "label", x: e + (right ? 1 : -1) * size * 1.3,
      y: -n - size * 0.6, "text-anchor": right ? "start" : "end", "font-size": unit * 3.5,
      "font-weight": 600, fill: vehicleColour(vehicle.id), stroke: "white", "stroke-width": 3,
      "paint-order": "stroke", "vector-effect": "non-scaling-stroke"}, String(vehicle.id)));
  }

  // The scale bar, bottom left, and the north arrow, top left.
  const [x0, y0] = [box.x + unit * 5, box.y + box.span - unit * 6];
  const scale = svgElement("g", {class: "scale"});
  scale.append(svgElement("path", {...line, stroke: INK, "stroke-width": 2,
    d: `M${x0},${y0 - unit} V${y0} H${x0 + length} V${y0 - unit}`}));
  scale.append(svgElement("text", {x: x0, y: y0 + unit * 4, "font-size": unit * 3.2,
    fill: INK}, `${length} m`));
  svg.append(scale);
  const [ax, ay] = [box.x + unit * 7, box.y + unit * 14];
  const north = svgElement("g", {class: "north"});
  north.append(svgElement("path", {d: `M${ax},${ay - unit * 8} L${ax + unit * 2.5},${ay} ` +
    `L${ax},${ay - unit * 2} L${ax - unit * 2.5},${ay} Z`, fill: INK}));
  north.append(svgElement("text", {x: ax - unit * 1.5, y: ay + unit * 4.5,
    "font-size": unit * 4, fill: INK}, "N"));
  svg.append(north);
}

// A small drawing of a line for the legend: `look` is PLANNED or FLOWN.
function legendLine(colour, look) {
  const drawing = svgElement("svg", {class: "key", viewBox: "0 0 24 8", width: 24, height: 8,
    "aria-hidden": "true"});
  drawing.append(svgElement("line", {x1: 1, y1: 4, x2: 23, y2: 4, stroke: colour, ...look}));
  return drawing;
}

// The legend, true to the map: a solid and a dashed line in each shown vehicle's colour,
// then the marks every map has.
function drawLegend(box, vehicleIds, hasWorld) {
  const item = (attributes, ...children) => {
    const found = document.createElement("li");
    for (const [key, value] of Object.entries(attributes)) found.setAttribute(key, value);
    found.append(...children);
    return found;
  };
  const items = vehicleIds.map((id) => item({"data-vehicle": id, class: "vehicle-key"},
    legendLine(vehicleColour(id), FLOWN), legendLine(vehicleColour(id), PLANNED),
    ` vehicle ${id}`));
  const home = svgElement("svg", {class: "key", viewBox: "0 0 24 8", width: 24, height: 8,
    "aria-hidden": "true"});
  home.append(svgElement("circle", {cx: 12, cy: 4, r: 3, fill: "white", stroke: INK}));
  items.push(item({class: "style-key"}, legendLine(INK, FLOWN), " flown"),
    item({class: "style-key"}, legendLine(INK, PLANNED), " planned"),
    item({class: "style-key"}, home, " home"));
  if (hasWorld) {
    const obstacle = svgElement("svg", {class: "key", viewBox: "0 0 24 8", width: 24,
      height: 8, "aria-hidden": "true"});
    obstacle.append(svgElement("rect", {x: 4, y: 0, width: 16, height: 8, fill: "#8c959f"}));
    items.push(item({class: "style-key"}, legendLine("#9a6700", {"stroke-width": 2}),
      " geofence"), item({class: "style-key"}, obstacle, " obstacle"));
  }
  box.replaceChildren(...items);
}

// --- over tiles (tml serve --tiles, --tile-url) ---------------------------------------------
// With a tile source (GET /tiles) and a known origin, the same scene is drawn with Leaflet
// (vendor/leaflet, unmodified) in latitude and longitude over the tiles, in #tile-map: the
// scene's points are placed by scene.place([n, e]) -> [latitude, longitude]. Without them
// the SVG drawing above is the map. A tile source that fails (errors, or nothing answers
// within NO_ANSWER_MS) is said under the map; the mission is drawn on either way.

const NO_ANSWER_MS = 10000;
const tiles = {source: undefined, map: null, overlays: null, layer: null, fitted: "",
  moved: false, asked: null, loaded: 0, failed: 0};

// Asked once the page has loaded: tiles that never come do not hold its load up.
window.addEventListener("load", () => fetch("/tiles")
  .then((answer) => answer.ok ? answer.json() : {source: null})
  .then((found) => { tiles.source = found && found.source ? found : null; })
  .catch(() => { tiles.source = null; }));

function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

function tileHost() {
  return tiles.source.source === "mbtiles" ? "the --tiles file"
    : new URL(tiles.source.url.replace(/[{}]/g, "")).host;
}

// Why the tiles do not show, or "" while they do (or may yet).
function tileProblem(now) {
  if (tiles.loaded) {
    return tiles.failed && tiles.source.source === "url"
      ? `${tiles.failed} tile(s) from ${tileHost()} failed to load.` : "";
  }
  if (tiles.failed) {
    return tiles.source.source === "mbtiles"
      ? "The --tiles file has no tiles here at this zoom: the mission is drawn without them."
      : `The tiles from ${tileHost()} do not load (${tiles.failed} answered with an error): ` +
        "the mission is drawn without them.";
  }
  if (tiles.asked !== null && now - tiles.asked > NO_ANSWER_MS) {
    return `${tileHost()} has not answered for ${Math.round((now - tiles.asked) / 1000)} s ` +
      "(no network?): the mission is drawn without tiles.";
  }
  return "";
}

function northArrow() {
  const control = L.control({position: "topright"});
  control.onAdd = () => {
    const box = L.DomUtil.create("div", "north-arrow leaflet-bar");
    const drawing = svgElement("svg", {class: "north", viewBox: "-12 -16 24 30", width: 24,
      height: 30, role: "img", "aria-label": "north is up"});
    drawing.append(svgElement("path", {d: "M0,-14 L7,6 L0,1 L-7,6 Z", fill: INK}));
    drawing.append(svgElement("text", {x: 0, y: 14, "text-anchor": "middle",
      "font-size": 9, fill: INK}, "N"));
    box.append(drawing);
    return box;
  };
  return control;
}

// The map, its view on `corners` (south-west, north-east) before any tile is asked for.
// Below the source's least zoom no tile is shown (scaling its tiles down would ask for
// thousands); above its greatest, its deepest tiles are enlarged.
function startTileMap(container, corners) {
  const source = tiles.source;
  const map = L.map(container, {maxZoom: Math.max(source.maxzoom + 3, 20), zoomSnap: 0.25});
  map.fitBounds(corners, {maxZoom: source.maxzoom});
  tiles.fitted = corners.flat().map((v) => v.toFixed(6)).join(",");
  map.attributionControl.setPrefix(
    '<a href="https://leafletjs.com" title="a JavaScript library for maps">Leaflet</a>');
  const layer = L.tileLayer(source.url, {minZoom: source.minzoom, maxZoom: map.getMaxZoom(),
    maxNativeZoom: source.maxzoom, attribution: escapeHtml(source.attribution || "")});
  layer.on("tileloadstart", () => { if (tiles.asked === null) tiles.asked = Date.now(); });
  layer.on("tileload", () => { tiles.loaded += 1; });
  layer.on("tileerror", () => { tiles.failed += 1; });
  layer.addTo(map);
  L.control.scale({imperial: false, position: "bottomleft"}).addTo(map);
  northArrow().addTo(map);
  // Once the operator moves the map, it stays where they put it.
  for (const kind of ["mousedown", "touchstart", "wheel", "keydown"]) {
    container.addEventListener(kind, () => { tiles.moved = true; }, {passive: true});
  }
  tiles.map = map;
  tiles.layer = layer;
  tiles.overlays = L.layerGroup().addTo(map);
}

function tagged(layer, attributes) {
  const element = layer.getElement && layer.getElement();
  if (element) {
    for (const [key, value] of Object.entries(attributes)) element.setAttribute(key, value);
  }
  return layer;
}

function vehicleIcon(vehicle) {
  const colour = vehicleColour(vehicle.id);
  const right = Number(vehicle.id) % 2 === 0;
  const drawing = svgElement("svg", {viewBox: "-30 -15 60 30", width: 60, height: 30});
  const arrow = svgElement("path", {d: "M0,-10 L7,10 L0,5 L-7,10 Z", fill: colour,
    stroke: "white", "stroke-width": 1.5, transform: `rotate(${vehicle.heading || 0})`});
  drawing.append(arrow, svgElement("text", {x: right ? 12 : -12, y: 4,
    "text-anchor": right ? "start" : "end", "font-size": 13, "font-weight": 600,
    fill: colour, stroke: "white", "stroke-width": 3, "paint-order": "stroke"},
  String(vehicle.id)));
  return L.divIcon({html: drawing, className: "vehicle-icon", iconSize: [60, 30],
    iconAnchor: [30, 15]});
}

// The scene over the tiles; returns the caption under the map.
function drawOverTiles(container, scene) {
  const place = scene.place;
  // The view: the scene's extent, until the operator moves the map.
  const box = sceneBounds(scene);
  const corners = [place([-box.y - box.span, box.x]), place([-box.y, box.x + box.span])];
  const key = corners.flat().map((v) => v.toFixed(6)).join(",");
  if (!tiles.map) startTileMap(container, corners);
  tiles.map.invalidateSize({pan: false});
  if (!tiles.moved && key !== tiles.fitted) {
    tiles.fitted = key;
    tiles.map.fitBounds(corners, {maxZoom: tiles.source.maxzoom});
  }
  const group = tiles.overlays;
  group.clearLayers();
  const world = scene.world || {};
  const line = (points, options) => L.polyline(points.map(place), {interactive: false,
    ...options});
  const fence = world.geofence;
  if (fence && fence.polygon && fence.polygon.length) {
    group.addLayer(L.polygon(fence.polygon.map(place), {className: "geofence", color: "#9a6700",
      weight: 2, fill: false, interactive: false}));
  }
  for (const obstacle of world.obstacles || []) {
    const look = {className: "obstacle", color: "#57606a", weight: 1, fillColor: "#8c959f",
      fillOpacity: 0.6};
    const shape = obstacle.shape === "cylinder"
      ? L.circle(place([obstacle.north, obstacle.east]), {...look, radius: obstacle.radius})
      : L.polygon(obstacle.polygon.map(place), look);
    group.addLayer(shape.bindTooltip(obstacle.name));
  }
  for (const track of scene.tracks || []) {
    if (track.points.length > 1) {
      tagged(line(track.points, {className: "track", color: vehicleColour(track.vehicle),
        weight: 5, opacity: 0.45}).addTo(group), {"data-vehicle": track.vehicle});
    }
  }
  for (const plan of scene.plans || []) {
    if (plan.points.length > 1) {
      const colour = plan.vehicle === null ? UNPICKED : vehicleColour(plan.vehicle);
      tagged(line(plan.points, {className: "plan", color: colour, weight: 1.5,
        dashArray: "6 4"}).addTo(group), {"data-plan": plan.key,
        ...(plan.vehicle === null ? {} : {"data-vehicle": plan.vehicle})});
    }
  }
  for (const home of scene.homes || []) {
    const [latitude, longitude] = place(home.point);
    tagged(L.circleMarker([latitude, longitude], {className: "home", radius: 5,
      color: vehicleColour(home.vehicle), weight: 2, fillColor: "white", fillOpacity: 1})
      .bindTooltip(`vehicle ${home.vehicle}: home`).addTo(group), {"data-vehicle": home.vehicle,
      "data-latitude": latitude.toFixed(7), "data-longitude": longitude.toFixed(7)});
  }
  for (const vehicle of scene.vehicles || []) {
    if (!vehicle.position) continue;
    const [latitude, longitude] = place(vehicle.position);
    const marker = L.marker([latitude, longitude], {icon: vehicleIcon(vehicle),
      interactive: false, keyboard: false, opacity: vehicle.faded ? 0.45 : 1}).addTo(group);
    tagged(marker, {"data-vehicle": vehicle.id, "data-latitude": latitude.toFixed(7),
      "data-longitude": longitude.toFixed(7), "data-up": vehicle.position[2].toFixed(2),
      title: `vehicle ${vehicle.id}: ${vehicle.position[2].toFixed(1)} m up`});
    marker.getElement().classList.add("vehicle");
  }

  const problem = tileProblem(Date.now());
  const shown = document.getElementById("tile-problem");
  shown.textContent = problem;
  shown.hidden = !problem;
  return tiles.source.source === "mbtiles"
    ? "Over the tiles of the --tiles file, north up."
    : `Over the tiles of ${tileHost()}, north up.`;
}

// The map of `scene` (see the top of this file): over tiles when the service names a tile
// source and the scene's origin is known, else in metres (the SVG `svg`). Returns the
// caption over tiles, null for the drawing in metres.
function drawSceneMap(svg, container, scene) {
  const overTiles = Boolean(tiles.source && scene.place && window.L);
  svg.toggleAttribute("hidden", overTiles);  // an SVG element has no `hidden` property
  container.hidden = !overTiles;
  if (!overTiles) {
    drawMap(svg, scene);
    return null;
  }
  return drawOverTiles(container, scene);
}
