// The map of the page: an SVG drawing in the local frame (metres north and east of home),
// north up, with a scale bar and a north arrow. It is drawn from a scene:
//   {world: {geofence, obstacles}, plans: {key: [[n, e, u], ...]},
//    tracks: {vehicle: [[n, e], ...]}, vehicles: [{id, position: [n, e, u], heading}]}
// SVG x is east and y is minus north, so that north is up.
"use strict";

const SVG = "http://www.w3.org/2000/svg";

function svgElement(name, attributes, text) {
  const element = document.createElementNS(SVG, name);
  for (const [key, value] of Object.entries(attributes || {})) {
    element.setAttribute(key, String(value));
  }
  if (text !== undefined) element.textContent = text;
  return element;
}

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
  for (const plan of Object.values(scene.plans || {})) points.push(...plan);
  for (const track of Object.values(scene.tracks || {})) points.push(...track);
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

const PALETTE = ["#cf222e", "#1f6feb", "#1a7f37", "#8250df", "#bc4c00", "#0a7ea4"];

function vehicleColour(id) {
  return PALETTE[(Number(id) - 1 + PALETTE.length) % PALETTE.length];
}

function drawMap(svg, scene) {
  const box = sceneBounds(scene);
  const unit = box.span / 100;  // one hundredth of the view, for sizes of marks and text
  svg.setAttribute("viewBox", `${box.x} ${box.y} ${box.span} ${box.span}`);
  svg.replaceChildren();
  const world = scene.world || {};
  const line = {"vector-effect": "non-scaling-stroke", fill: "none"};

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
  svg.append(svgElement("circle", {class: "home", cx: 0, cy: 0, r: unit * 1.2,
    fill: "none", stroke: "#1d2430", "vector-effect": "non-scaling-stroke"}));

  for (const [key, plan] of Object.entries(scene.plans || {})) {
    if (plan.length > 1) {
      svg.append(svgElement("path", {...line, class: "plan", "data-vehicle": key,
        stroke: "#1f6feb", "stroke-width": 1.5, "stroke-dasharray": "6 4", d: pathOf(plan)}));
    }
  }
  for (const [id, track] of Object.entries(scene.tracks || {})) {
    if (track.length > 1) {
      svg.append(svgElement("path", {...line, class: "track", "data-vehicle": id,
        stroke: vehicleColour(id), "stroke-width": 2, d: pathOf(track)}));
    }
  }
  for (const vehicle of scene.vehicles || []) {
    if (!vehicle.position) continue;
    const [n, e, u] = vehicle.position;
    const marker = svgElement("g", {class: "vehicle", "data-vehicle": vehicle.id,
      "data-north": n.toFixed(2), "data-east": e.toFixed(2), "data-up": u.toFixed(2),
      transform: `translate(${e} ${-n}) rotate(${vehicle.heading || 0})`});
    const size = unit * 2.5;
    marker.append(svgElement("path", {d: `M0,${-size} L${size * 0.7},${size} L0,${size * 0.5} ` +
      `L${-size * 0.7},${size} Z`, fill: vehicleColour(vehicle.id), stroke: "white",
      "vector-effect": "non-scaling-stroke"}));
    svg.append(marker);
    svg.append(svgElement("text", {x: e + size * 1.2, y: -n - size * 1.2,
      "font-size": unit * 3.5, fill: "#1d2430"}, String(vehicle.id)));
  }

  // The scale bar, bottom left, and the north arrow, top left.
  const length = niceLength(box.span / 5);
  const [x0, y0] = [box.x + unit * 5, box.y + box.span - unit * 6];
  const scale = svgElement("g", {class: "scale"});
  scale.append(svgElement("path", {...line, stroke: "#1d2430", "stroke-width": 2,
    d: `M${x0},${y0 - unit} V${y0} H${x0 + length} V${y0 - unit}`}));
  scale.append(svgElement("text", {x: x0, y: y0 + unit * 4, "font-size": unit * 3.2,
    fill: "#1d2430"}, `${length} m`));
  svg.append(scale);
  const [ax, ay] = [box.x + unit * 7, box.y + unit * 14];
  const north = svgElement("g", {class: "north"});
  north.append(svgElement("path", {d: `M${ax},${ay - unit * 8} L${ax + unit * 2.5},${ay} ` +
    `L${ax},${ay - unit * 2} L${ax - unit * 2.5},${ay} Z`, fill: "#1d2430"}));
  north.append(svgElement("text", {x: ax - unit * 1.5, y: ay + unit * 4.5,
    "font-size": unit * 4, fill: "#1d2430"}, "N"));
  svg.append(north);
}
