// The page of tml serve: missions, runs, vehicles and the live view of a run, all through
// the service's HTTP API (docs/serve.md). Plain script, no build step, nothing fetched
// from anywhere but the service.
//
// Time: every line of a run's flight log carries its own time stamps: `t` on the run's
// clock and `mission_time`, seconds since the mission's first task started (null before).
// The page shows mission time: the line's own, else `t` less the `t` of the mission's
// start (its first `mission` line), negative before it; while the mission has not
// started, seconds since the run started. Nothing is stamped with the time the page
// received it, so a reload shows the same times.
//
// Space: every vehicle has its own home (the origin of its telemetry's local frame). The
// map draws them all in one frame, metres north and east of the first vehicle's home:
// positions come as latitude and longitude (`global`) and are projected around that home.
"use strict";

const LIVE = ["waiting", "running", "paused"];
const MAX_LINES = 200;          // events and messages kept in the lists
const EVENT_KINDS = ["event", "safety", "mission", "error", "vehicle", "control", "link",
  "taken", "pick", "release"];
const SAFE_STATES = {rtl: "return to launch", land: "land where they are",
  hold: "hold where they are"};
const GPS_FIXES = ["no GPS", "no fix", "2D fix", "3D fix", "DGPS", "RTK float", "RTK fixed",
  "static", "PPP"];

function freshLog() {
  return {
    runStart: null,             // t of the run's first line
    missionStart: null,         // t at which its mission's clock read 0
    events: [],                 // {t, mt, wall, who, text, kind}, oldest first
    messages: [],               // the autopilots' messages: {t, mt, wall, who, text, severity}
    tracks: {},                 // per vehicle id: [{global, position}], from telemetry lines
    picked: {},                 // per role: the vehicles flying it
  };
}

const state = {
  token: sessionStorage.getItem("tml-token") || "",
  missions: [], runs: [], vehicles: [],
  chosenMission: null,          // id of the mission chosen in the list
  run: null,                    // the run shown: its JSON from GET /runs/{id}
  pinned: false,                // the operator chose the run shown (else: the live one)
  outline: null,                // the shown run's mission: tree and world
  report: null,                 // the verifier's report of that mission: the planned paths
  log: freshLog(),              // what the shown run's flight log said so far
  stream: null,                 // AbortController of the run's event stream
  choosing: false,              // a run is being chosen by default
  commandSaid: {},              // per vehicle id: what its last command from here came to
  ticks: 0,
};

const $ = (selector) => document.querySelector(selector);

function element(name, attributes, ...children) {
  const found = document.createElement(name);
  for (const [key, value] of Object.entries(attributes || {})) {
    if (key === "class") found.className = value;
    else if (key.startsWith("data-")) found.setAttribute(key, value);
    else found[key] = value;
  }
  found.append(...children.filter((c) => c !== null && c !== undefined));
  return found;
}

function coloured(found, vehicleId) {
  found.style.setProperty("--vehicle", vehicleColour(vehicleId));
  return found;
}

function vehicleList(ids) {
  return ids.length === 1 ? `vehicle ${ids[0]}` : `vehicles ${ids.join(", ")}`;
}

// --- the API -------------------------------------------------------------------------------

class Refused extends Error {
  constructor(status, body) {
    super(body && body.error ? body.error : `HTTP ${status}`);
    this.status = status;
    this.body = body || {};
  }
}

function headers(extra) {
  const found = {...(extra || {})};
  if (state.token) found.Authorization = `Bearer ${state.token}`;
  return found;
}

async function api(method, path, body, type) {
  const options = {method: method, headers: headers()};
  if (body instanceof FormData) {
    options.body = body;
  } else if (body !== undefined) {
    options.body = JSON.stringify(body);
    options.headers["Content-Type"] = type || "application/json";
  }
  const answer = await fetch(path, options);
  if (answer.status === 401) askToken();
  const text = await answer.text();
  const found = text ? JSON.parse(text) : null;
  if (!answer.ok) throw new Refused(answer.status, found);
  return found;
}

function askToken() {
  $("#token-form").hidden = false;
  $("#service").textContent = "this service needs a token";
}

$("#token-form").addEventListener("submit", (event) => {
  event.preventDefault();
  state.token = $("#token").value.trim();
  sessionStorage.setItem("tml-token", state.token);
  $("#token-form").hidden = true;
  refresh();
});

// --- asking before a command that moves a vehicle --------------------------------------------

// Whether the operator confirms `question`: an in-page dialog, Cancel focused, so that
// neither a stray click nor Enter sends a vehicle anywhere.
function confirmCommand(question, label) {
  const dialog = $("#confirm");
  $("#confirm-text").textContent = question;
  $("#confirm-ok").textContent = label;
  dialog.returnValue = "";
  return new Promise((resolve) => {
    dialog.addEventListener("close", () => resolve(dialog.returnValue === "ok"), {once: true});
    dialog.showModal();
    $("#confirm-cancel").focus();
  });
}

// --- missions ------------------------------------------------------------------------------

$("#upload-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const file = $("#mission-file").files[0];
  const result = $("#upload-result");
  if (!file) {
    result.replaceChildren(element("p", {class: "error", textContent: "choose a mission file"}));
    return;
  }
  const form = new FormData();
  form.append("file", file, file.name);
  try {
    const mission = await api("POST", "/missions", form);
    result.replaceChildren(element("p", {class: "ok",
      textContent: `${mission.filename}: valid, uploaded as “${mission.name}”`}));
    state.chosenMission = mission.id;
    await refreshMissions();
  } catch (error) {
    showUploadErrors(result, error, await file.text());
  }
});

// Every diagnostic, each with its line quoted in full (wrapped, never cut) and the
// offending word marked at its column.
function showUploadErrors(result, error, source) {
  const lines = source.split(/\r?\n/);
  const shown = [element("p", {class: "error", textContent: error.message})];
  for (const found of error.body.diagnostics || []) {
    const where = `line ${found.line}, column ${found.column}`;
    const item = element("div", {class: "diagnostic", "data-line": found.line},
      element("span", {class: found.severity === "error" ? "error" : "",
        textContent: `${where}: ${found.severity} ${found.code}: ${found.message}`}));
    if (found.line >= 1 && found.line <= lines.length) {
      const text = lines[found.line - 1];
      const quoted = element("pre", {});
      const at = found.column >= 1 ? Math.min(found.column - 1, text.length) : -1;
      if (at >= 0) {
        // The name there, with its "<" or "</" when the column is the start of a tag.
        const word = /^<?\/?[\w.:-]*/.exec(text.slice(at))[0] || text.slice(at, at + 1);
        quoted.append(text.slice(0, at), element("mark", {textContent: word}),
          text.slice(at + word.length));
      } else {
        quoted.textContent = text;
      }
      item.append(quoted);
    }
    if (found.hint) item.append(element("small", {textContent: `hint: ${found.hint}`}));
    shown.push(item);
  }
  result.replaceChildren(...shown);
}

async function refreshMissions() {
  state.missions = await api("GET", "/missions");
  const list = $("#missions");
  list.replaceChildren(...state.missions.map((mission) => {
    const item = element("li", {"data-mission": mission.id,
      class: mission.id === state.chosenMission ? "chosen" : ""},
      element("span", {textContent: mission.name}),
      element("small", {textContent: `${mission.filename} · ${mission.id}`}));
    item.addEventListener("click", () => { state.chosenMission = mission.id; refreshMissions(); });
    return item;
  }));
  const chosen = state.missions.find((m) => m.id === state.chosenMission);
  $("#start-form").hidden = !chosen;
  if (chosen) $("#chosen-mission").textContent = chosen.name;
  drawVehicleChoice();
}

function drawVehicleChoice() {
  const box = $("#vehicle-choice");
  const checked = new Set([...box.querySelectorAll("input:checked")].map((i) => Number(i.value)));
  box.replaceChildren(...state.vehicles.map((vehicle) => element("label", {},
    element("input", {type: "checkbox", value: vehicle.id, checked: checked.has(vehicle.id),
      disabled: vehicle.run !== null}),
    ` vehicle ${vehicle.id}${vehicle.run ? " (in a run)" : ""} `)));
}

$("#verify").addEventListener("click", async () => {
  const result = $("#start-result");
  try {
    const report = await api("POST", `/missions/${state.chosenMission}/verify`, {});
    result.replaceChildren(element("p", {class: report.feasible ? "ok" : "error",
      textContent: report.feasible ? "feasible"
        : `infeasible: ${report.violations.map((v) => v.message).join("; ")}`}));
  } catch (error) {
    result.replaceChildren(element("p", {class: "error", textContent: error.message}));
  }
});

$("#start").addEventListener("click", async () => {
  const result = $("#start-result");
  const vehicles = [...$("#vehicle-choice").querySelectorAll("input:checked")]
    .map((i) => Number(i.value));
  const request = {mission: state.chosenMission, safe_state: $("#safe-state").value};
  if (vehicles.length) request.vehicles = vehicles;
  const mission = state.missions.find((m) => m.id === state.chosenMission);
  const question = `Start “${mission ? mission.name : state.chosenMission}” on ` +
    `${vehicles.length ? vehicleList(vehicles) : "the first free vehicle"}? They take off and ` +
    `fly the mission; their safe state: ${SAFE_STATES[request.safe_state]}.`;
  if (!await confirmCommand(question, "Start run")) return;
  try {
    const run = await api("POST", "/runs", request);
    result.replaceChildren(element("p", {class: "ok", textContent: `run ${run.id} started`}));
    state.pinned = true;
    await showRun(run.id);
  } catch (error) {
    const violations = (error.body.report ? error.body.report.violations : error.body.violations)
      || [];
    result.replaceChildren(element("p", {class: "error", textContent: error.message}),
      ...violations.map((v) => element("p", {class: "error", textContent: v.message})));
  }
});

// --- runs ----------------------------------------------------------------------------------

async function refreshRuns() {
  state.runs = (await api("GET", "/runs")).sort((a, b) => a.created - b.created);
  drawRuns();
  const wanted = defaultRun();
  if (wanted && !state.choosing) {
    state.choosing = true;
    try {
      await showRun(wanted);
    } finally {
      state.choosing = false;
    }
  }
}

function drawRuns() {
  const list = $("#runs");
  list.replaceChildren(...[...state.runs].reverse().map((run) => {
    const item = element("li", {"data-run": run.id,
      class: state.run && state.run.id === run.id ? "chosen" : ""},
      element("span", {textContent: `${run.mission.name} `}),
      element("span", {class: `state state-${stateClass(run.status)}`, textContent: run.status}),
      element("small", {textContent: `run ${run.id} · ${vehicleList(run.vehicles)}`}));
    item.addEventListener("click", () => { state.pinned = true; showRun(run.id); });
    return item;
  }));
}

// The run to show when the operator has not chosen one: the newest that flies, else
// (nothing shown yet) the newest of all. A live run shown stays shown.
function defaultRun() {
  if (state.pinned && state.run) return null;
  if (state.run && LIVE.includes(state.run.status)) return null;
  const newest = [...state.runs].reverse();
  const wanted = newest.find((run) => LIVE.includes(run.status)) || (state.run ? null : newest[0]);
  return wanted && !(state.run && state.run.id === wanted.id) ? wanted.id : null;
}

function stateClass(status) {
  return {completed: "done", waiting: "pending", interrupted: "aborted", taken: "aborted"}[status]
    || status;
}

async function showRun(runId) {
  if (state.stream) state.stream.abort();
  state.stream = null;
  const run = await api("GET", `/runs/${runId}`);
  state.run = run;
  state.log = freshLog();
  state.outline = null;
  state.report = null;
  drawRun();
  drawRuns();
  const controller = new AbortController();
  state.stream = controller;
  try {
    const outline = await api("GET", `/missions/${run.mission.id}`);
    const report = await api("POST", `/missions/${run.mission.id}/verify`,
      {profile: run.options.profile || "quadcopter"});
    if (state.stream === controller) {
      state.outline = outline;
      state.report = report;
    }
  } catch (error) {
    // The mission was deleted since: the run's task states are shown without the tree.
  }
  if (state.stream !== controller) return;  // another run was chosen meanwhile
  drawRun();
  follow(runId, controller);
}

// The run's records as Server-Sent Events, read with fetch so that the token is sent.
async function follow(runId, controller) {
  let answer;
  try {
    answer = await fetch(`/runs/${runId}/stream`, {headers: headers(), signal: controller.signal});
  } catch (error) {
    return;
  }
  if (!answer.ok || !answer.body) return;
  const reader = answer.body.getReader();
  const decoder = new TextDecoder();
  let buffer = "";
  try {
    for (;;) {
      const {value, done} = await reader.read();
      if (done) break;
      buffer += decoder.decode(value, {stream: true});
      let cut;
      while ((cut = buffer.search(/\r?\n\r?\n/)) >= 0) {
        const block = buffer.slice(0, cut);
        buffer = buffer.slice(cut).replace(/^\r?\n\r?\n/, "");
        handleEvent(controller, block);
      }
    }
  } catch (error) {
    // Aborted: another run is shown now.
  }
}

function handleEvent(controller, block) {
  let kind = "message";
  const data = [];
  for (const line of block.split(/\r?\n/)) {
    if (line.startsWith("event:")) kind = line.slice(6).trim();
    else if (line.startsWith("data:")) data.push(line.slice(5).replace(/^ /, ""));
  }
  if (state.stream !== controller || !data.length) return;
  const payload = JSON.parse(data.join("\n"));
  if (kind === "end") {
    state.run = payload;
    drawRun();
    refreshRuns().catch(() => {});
  } else if (kind === "record") {
    record(payload);
  } else if (kind === "tasks") {
    // Every task's state per vehicle, as the service folds the log (rounds, jumps,
    // resumes): the page shows it, it does not fold the records itself.
    if (state.run) {
      state.run.tasks = payload;
      later("tasks");
    }
  }
}

// One line of the shown run's flight log.
function record(line) {
  const run = state.run;
  const log = state.log;
  const whose = line.vehicle === undefined || line.vehicle === null ? "" : String(line.vehicle);
  const t = Number(line.t);
  const stamp = {t: t, mt: typeof line.mission_time === "number" ? line.mission_time : null,
    wall: line.wall || ""};
  if (log.runStart === null) log.runStart = t;
  if (log.missionStart === null && stamp.mt !== null) {
    log.missionStart = t - stamp.mt;
    later("lists");
  }
  if (line.kind === "telemetry") {
    if (!log.tracks[whose]) log.tracks[whose] = [];
    log.tracks[whose].push({global: line.global, position: line.position});
  } else if (line.kind === "mission") {
    if (log.missionStart === null && !line.status) {
      log.missionStart = t - Number(line.elapsed || 0);  // a continued run: its clock goes on
      later("lists");
    }
    if (run.status === "waiting") {
      run.status = "running";
      later("bar");
    }
  } else if (line.kind === "pick" && line.role && line.vehicles) {
    log.picked[line.role] = line.vehicles.map(String);
  } else if (line.kind === "release" && line.role && log.picked[line.role]) {
    log.picked[line.role] = log.picked[line.role].filter((v) => v !== whose);
  } else if (line.kind === "autopilot") {
    // A reason not to arm is no alarm, though the autopilot says it critical: it is said
    // only while disarmed (after every landing too), as tml's own views show it
    // (tml.vehicle.shown_severity).
    const calm = /^(PreArm|Arm):/.test(line.text || "") && line.level < 6;
    keep(log.messages, {...stamp, who: whose, text: line.text,
      severity: calm ? "info" : line.severity});
    later("lists");
  }
  if (EVENT_KINDS.includes(line.kind) ||
      (line.kind === "action" && /fail|infeasible/.test(line.message || "")) ||
      (line.kind === "result" && line.ok === false)) {
    keep(log.events, {...stamp, who: whose, text: line.message || line.reason || line.kind,
      kind: line.kind});
    later("lists");
  }
}

function keep(list, item) {
  list.push(item);
  if (list.length > MAX_LINES) list.shift();
}

// Redraws asked for while a stream's records come in, done once they stop coming.
const pending = new Set();
let drawing = null;
function later(what) {
  pending.add(what);
  if (drawing === null) {
    drawing = setTimeout(() => {
      drawing = null;
      if (pending.has("bar")) drawRunBar();
      if (pending.has("tasks")) drawTasks();
      if (pending.has("lists")) drawLists();
      pending.clear();
    }, 30);
  }
}

function timeText(item) {
  const log = state.log;
  const origin = log.missionStart !== null ? log.missionStart : log.runStart;
  const seconds = item.mt !== null ? item.mt : item.t - (origin === null ? item.t : origin);
  return `${seconds < -0.05 ? "−" : ""}${Math.abs(seconds).toFixed(1)} s`;
}

function drawLists() {
  const log = state.log;
  const base = !state.run ? "" : log.missionStart !== null ? "(mission time)"
    : "(since the run started; the mission has not)";
  for (const caption of document.querySelectorAll(".time-base")) caption.textContent = base;
  const line = (item, extra) => element("li", {class: extra, "data-t": item.t},
    element("span", {class: "t", textContent: timeText(item), title: item.wall}),
    element("span", {}, (item.who ? `vehicle ${item.who}: ` : "") + item.text));
  $("#events").replaceChildren(...[...log.events].reverse().map(
    (item) => line(item, `kind-${item.kind}`)));
  $("#messages").replaceChildren(...[...log.messages].reverse().map(
    (item) => line(item, `sev-${item.severity}`)));
}

function drawRun() {
  drawRunBar();
  drawTasks();
  drawLists();
  drawTheMap();
}

function drawRunBar() {
  const run = state.run;
  const live = run && LIVE.includes(run.status);
  $("#run-status").textContent = run
    ? `run ${run.id}: ${run.mission.name}: ${run.status}` +
      (run.reason ? ` (${run.reason})` : "") + (run.exit_code !== null ? `, exit ${run.exit_code}` : "")
    : "no run yet";
  $("#pause").disabled = !live || run.status === "paused";
  $("#resume").disabled = !live || run.status !== "paused";
  $("#abort").disabled = !live;
  $("#continue").disabled = !run || run.status !== "interrupted";
  $("#jump").disabled = $("#jump-task").disabled = !live;
}

function taskList(tasks) {
  return tasks.flatMap((task) => [task, ...taskList(task.children), ...taskList(task.on_error)]);
}

function drawTasks() {
  const run = state.run;
  const box = $("#tasks");
  if (!run || !run.tasks) { box.replaceChildren(); return; }
  const whose = Object.keys(run.tasks).sort((a, b) => (Number(a) || 0) - (Number(b) || 0));
  const tree = state.outline ? state.outline.tasks : Object.keys(run.tasks[whose[0]] || {}).map(
    (path) => ({name: path, path: path, children: [], on_error: []}));
  const branch = (tasks) => element("ul", {}, ...tasks.map((task) => element("li",
    {"data-task": task.path},
    element("span", {class: "name", textContent: task.name}),
    ...whose.filter((w) => run.tasks[w][task.path] !== undefined).map((w) => {
      const value = run.tasks[w][task.path];
      const badge = element("span", {class: `state state-${value}`, "data-vehicle": w,
        textContent: `${w ? `vehicle ${w}` : "fleet"}: ${value}`});
      return w ? coloured(badge, w) : badge;
    }),
    task.children.length ? branch(task.children) : null,
    task.on_error && task.on_error.length ? branch(task.on_error) : null)));
  box.replaceChildren(branch(tree));
  const select = $("#jump-task");
  const paths = taskList(tree).map((t) => t.path);
  if ([...select.options].map((o) => o.value).join("\n") !== paths.join("\n")) {
    select.replaceChildren(...paths.map((p) => element("option", {value: p, textContent: p})));
  }
}

// --- the map: one frame for the fleet ---------------------------------------------------------

const WGS84_A = 6378137.0;
const WGS84_E2 = 6.69437999014e-3;

// Metres north and east of `origin` (a home) of a latitude and longitude: the local tangent
// plane, exact to a few centimetres over kilometres.
function project(origin, latitude, longitude) {
  const phi = origin.latitude * Math.PI / 180;
  const w = Math.sqrt(1 - WGS84_E2 * Math.sin(phi) ** 2);
  const meridian = WGS84_A * (1 - WGS84_E2) / (w * w * w);
  const normal = WGS84_A / w;
  return [(latitude - origin.latitude) * Math.PI / 180 * meridian,
          (longitude - origin.longitude) * Math.PI / 180 * normal * Math.cos(phi)];
}

// Its inverse: the latitude and longitude of a point metres north and east of `origin`.
function unproject(origin, [north, east]) {
  const phi = origin.latitude * Math.PI / 180;
  const w = Math.sqrt(1 - WGS84_E2 * Math.sin(phi) ** 2);
  const meridian = WGS84_A * (1 - WGS84_E2) / (w * w * w);
  const normal = WGS84_A / w;
  return [origin.latitude + north / meridian * 180 / Math.PI,
          origin.longitude + east / (normal * Math.cos(phi)) * 180 / Math.PI];
}

function shownVehicleIds() {
  return state.run ? state.run.vehicles : state.vehicles.map((v) => v.id);
}

// The shared frame: its origin (the first shown vehicle whose home is known) and where
// each vehicle's home and positions are in it.
function sharedFrame() {
  const homes = {};
  for (const v of state.vehicles) if (v.home) homes[v.id] = v.home;
  const originVehicle = shownVehicleIds().find((id) => homes[id]);
  const origin = originVehicle === undefined ? null : homes[originVehicle];
  const offset = (id) => origin && homes[id]
    ? project(origin, homes[id].latitude, homes[id].longitude) : [0, 0];
  const point = (id, global, position) => {
    if (origin && global && (position || homes[id])) {
      const [n, e] = project(origin, global[0], global[1]);
      return [n, e, position ? position[2] : global[2] - homes[id].altitude];
    }
    if (!position) return null;
    const [dn, de] = offset(id);
    return [position[0] + dn, position[1] + de, position[2]];
  };
  return {origin: origin, originVehicle: originVehicle, homes: homes, offset: offset,
    point: point};
}

function shifted(points, [dn, de]) {
  return points.map(([n, e, ...rest]) => [n + dn, e + de, ...rest]);
}

// The mission's world (geofence, obstacles: metres from the world's home) in the frame: at
// its declared home, else at the origin.
function worldInFrame(frame) {
  const world = state.outline ? state.outline.world : {};
  const home = world.home;
  const [dn, de] = home && home.declared && frame.origin
    ? project(frame.origin, home.latitude, home.longitude) : [0, 0];
  const fence = world.geofence && world.geofence.polygon
    ? {...world.geofence, polygon: shifted(world.geofence.polygon, [dn, de])} : world.geofence;
  const obstacles = (world.obstacles || []).map((o) => o.shape === "cylinder"
    ? {...o, north: o.north + dn, east: o.east + de}
    : {...o, polygon: shifted(o.polygon, [dn, de])});
  return {geofence: fence, obstacles: obstacles};
}

// The verifier's predicted path for each vehicle, from its own home: the whole mission for
// every vehicle of a mission without roles, a role's part for the vehicles picked for it
// (a role not picked yet is drawn from the origin, in grey).
function plansInFrame(frame) {
  if (!state.report || !state.run) return [];
  const actions = state.report.actions.filter((a) => !a.event);
  const roles = state.outline ? state.outline.roles.map((r) => r.name) : [];
  const pathOf = (wanted) => [[0, 0, 0], ...actions.filter(wanted).flatMap((a) => a.path)];
  const plans = [];
  if (!roles.length) {
    const path = pathOf((a) => !a.role);
    for (const id of state.run.vehicles) {
      plans.push({key: `vehicle ${id}`, vehicle: id, points: shifted(path, frame.offset(id))});
    }
  }
  for (const role of roles) {
    const path = pathOf((a) => a.role === role);
    const picked = state.log.picked[role] || [];
    for (const id of picked) {
      plans.push({key: `role ${role} vehicle ${id}`, vehicle: Number(id),
        points: shifted(path, frame.offset(Number(id)))});
    }
    if (!picked.length) plans.push({key: `role ${role}`, vehicle: null, points: path});
  }
  return plans;
}

function drawTheMap() {
  const frame = sharedFrame();
  const shown = shownVehicleIds();
  const tracks = Object.entries(state.log.tracks).map(([id, samples]) => ({vehicle: id,
    points: samples.map((s) => frame.point(Number(id), s.global, s.position)).filter((p) => p)}));
  const world = worldInFrame(frame);
  const caption = drawSceneMap($("#map"), $("#tile-map"), {
    world: world,
    plans: plansInFrame(frame),
    tracks: tracks,
    homes: shown.filter((id) => frame.homes[id]).map((id) => ({vehicle: id,
      point: frame.offset(id)})),
    vehicles: state.vehicles.filter((v) => shown.includes(v.id)).map((v) => ({id: v.id,
      position: frame.point(v.id, v.global, v.position), heading: v.heading})),
    place: frame.origin ? (point) => unproject(frame.origin, point) : null,
  });
  drawLegend($("#legend"), shown,
    Boolean((world.geofence && world.geofence.polygon && world.geofence.polygon.length)
      || world.obstacles.length));
  $("#frame").textContent = caption || (frame.origin
    ? `Metres from vehicle ${frame.originVehicle}'s home, north up; every vehicle where it is.`
    : "Metres from each vehicle's own home (no home known yet), north up.");
}

// --- controls ------------------------------------------------------------------------------

async function control(action, body) {
  const result = $("#control-result");
  try {
    state.run = await api("POST", `/runs/${state.run.id}/${action}`, body);
    result.replaceChildren();
    drawRun();
    await refreshRuns();
  } catch (error) {
    result.replaceChildren(element("span", {class: "error", textContent: error.message}));
  }
}

function runName(run) {
  return `run ${run.id} (“${run.mission.name}”)`;
}

$("#pause").addEventListener("click", () => control("pause"));
$("#resume").addEventListener("click", async () => {
  const run = state.run;
  if (await confirmCommand(`Resume ${runName(run)}? ${vehicleList(run.vehicles)} fly on ` +
      "where the mission sends them.", "Resume")) {
    await control("resume");
  }
});
$("#abort").addEventListener("click", async () => {
  const run = state.run;
  const safe = SAFE_STATES[run.options.safe_state] || run.options.safe_state;
  if (await confirmCommand(`Abort ${runName(run)}? The mission ends and ` +
      `${vehicleList(run.vehicles)} go to their safe state: ${safe}.`, "Abort run")) {
    await control("abort");
  }
});
$("#jump").addEventListener("click", async () => {
  const run = state.run;
  const task = $("#jump-task").value;
  if (await confirmCommand(`Jump to the task “${task}” in ${runName(run)}? What runs now ` +
      `stops and ${vehicleList(run.vehicles)} fly on from that task.`, "Jump")) {
    await control("jump", {task: task});
  }
});
// An interrupted run goes on as a new run, which is then shown.
$("#continue").addEventListener("click", async () => {
  const run = state.run;
  if (!await confirmCommand(`Continue ${runName(run)}? A new run flies the rest of its ` +
      `mission on ${vehicleList(run.vehicles)}.`, "Continue")) return;
  const result = $("#control-result");
  try {
    const next = await api("POST", `/runs/${run.id}/continue`);
    result.replaceChildren();
    state.pinned = true;
    await showRun(next.id);
  } catch (error) {
    result.replaceChildren(element("span", {class: "error", textContent: error.message}));
  }
});

// --- vehicles --------------------------------------------------------------------------------

// A value with its unit, "–" while unknown, never a negative zero.
function number(value, digits, unit) {
  if (value === null || value === undefined) return "–";
  const shown = Number(value).toFixed(digits);
  return `${Number(shown) === 0 ? (0).toFixed(digits) : shown}${unit}`;
}

// What the operator reads of each vehicle: [field, label, value].
function vehicleFields(v) {
  return [["mode", "mode", v.mode || "–"],
    ["armed", "armed", v.armed ? (v.landed ? "armed, on the ground" : "armed, flying")
      : "disarmed"],
    ["gps", "GPS", v.gps_fix === null ? "–" : (GPS_FIXES[v.gps_fix] || `fix ${v.gps_fix}`)],
    ["satellites", "satellites", number(v.satellites, 0, "")],
    ["battery", "battery", number(v.battery, 0, " %")],
    ["voltage", "voltage", number(v.voltage, 1, " V")],
    ["altitude", "altitude", v.position ? number(v.position[2], 1, " m") : "–"],
    ["climb", "climb", number(v.climb, 1, " m/s")],
    ["speed", "speed", number(v.ground_speed, 1, " m/s")],
    ["heading", "heading", number(v.heading, 0, "°")],
    ["home", "from home",
      v.position ? number(Math.hypot(v.position[0], v.position[1]), 0, " m") : "–"]];
}

function drawTelemetry() {
  const box = $("#telemetry");
  box.replaceChildren(...state.vehicles.map((v) => {
    const list = element("dl", {}, ...vehicleFields(v).flatMap(([key, label, value]) => [
      element("dt", {textContent: label}), element("dd", {"data-field": key, textContent: value})]));
    list.append(element("dd", {class: "note", "data-field": "run",
      textContent: v.run ? `in run ${v.run}` : "in no run"}));
    if (v.awaiting && v.awaiting.length) {
      list.append(element("dd", {class: "note warn", "data-field": "awaiting",
        textContent: `not ready: ${v.awaiting.join(", ")}`}));
    }
    if (v.status_text) {
      list.append(element("dd", {class: "note", "data-field": "status-text",
        title: "the autopilot's last message", textContent: `“${v.status_text}”`}));
    }
    const said = state.commandSaid[v.id] || commandSeen(v.command);
    if (said) {
      list.append(element("dd", {class: `note${said.error ? " error" : ""}`,
        "data-field": "command", textContent: said.text}));
    }
    const buttons = element("div", {class: "commands"}, ...Object.entries(COMMANDS).map(
      ([command, {label}]) => element("button", {type: "button", textContent: label,
        class: command === "disarm" ? "danger" : "", "data-command": command,
        "data-vehicle": v.id, title: COMMANDS[command].title})));
    return coloured(element("article", {class: "vehicle-card", "data-vehicle": v.id},
      element("h3", {}, `vehicle ${v.id}`, element("small", {textContent: v.vehicle_type}),
        element("span", {class: `link link-${v.link}`, "data-field": "link",
          textContent: `link ${v.link}`})),
      list, buttons), v.id);
  }));
}

// --- an operator's command to a vehicle: RTL, land, hold, disarm ------------------------------

const COMMANDS = {
  rtl: {label: "RTL", title: "return to launch", ask: "return to launch and land"},
  land: {label: "Land", title: "land where it is", ask: "land where it is"},
  hold: {label: "Hold", title: "stop and hold where it is", ask: "stop and hold where it is"},
  disarm: {label: "Disarm", title: "stop the motors (only on the ground)",
    ask: "stop its motors (refused while it flies)"},
};

// The last command the service saw through for a vehicle (GET /vehicles), in words.
function commandSeen(seen) {
  if (!seen) return null;
  return {text: `${COMMANDS[seen.command].label}: ${seen.outcome} (${seen.detail})`,
    error: ["refused", "unanswered", "not confirmed"].includes(seen.outcome)};
}

// One handler for every card's buttons: the cards are drawn again every second.
$("#telemetry").addEventListener("click", async (event) => {
  const button = event.target.closest("button[data-command]");
  if (!button) return;
  const command = button.dataset.command;
  const id = Number(button.dataset.vehicle);
  const vehicle = state.vehicles.find((v) => v.id === id);
  const held = !(vehicle && vehicle.run) ? "" : command === "hold" ?
    ` Run ${vehicle.run}, which holds it, pauses: every vehicle of that run holds.` :
    ` Run ${vehicle.run}, which holds it, ends: every vehicle of that run goes to ` +
    `${COMMANDS[command].label}` + (command === "disarm" ? " (its safe state)" : "") + ".";
  if (!await confirmCommand(`${COMMANDS[command].label} vehicle ${id}? It is told to ` +
      `${COMMANDS[command].ask}, now.${held}`, `${COMMANDS[command].label} vehicle ${id}`)) {
    return;
  }
  state.commandSaid[id] = {text: `${COMMANDS[command].label}: sent…`};
  drawTelemetry();
  // Once answered, the card says what the service saw through (GET /vehicles: sent,
  // accepted, then done when the vehicle's telemetry confirms it by its motion, or not
  // confirmed with what was seen; refused with the reason); what it never saw (no token,
  // an unreachable service) is said here.
  try {
    await api("POST", `/vehicles/${id}/command`, {command: command});
    delete state.commandSaid[id];
  } catch (error) {
    if (error.status === 409) delete state.commandSaid[id];
    else state.commandSaid[id] = {text: `${COMMANDS[command].label}: ${error.message}`,
      error: true};
  }
  await refreshVehicles();
  await refreshRuns();
});

async function refreshVehicles() {
  state.vehicles = await api("GET", "/vehicles");
  drawTelemetry();
  drawVehicleChoice();
  drawTheMap();
}

// --- every second ----------------------------------------------------------------------------

async function refresh() {
  try {
    const status = await api("GET", "/status");
    $("#service").textContent = `${status.instance} · ${status.vehicles.length} vehicle(s) · ` +
      `${status.storage} · tml ${status.version}`;
    await refreshVehicles();
    await refreshMissions();
    await refreshRuns();
  } catch (error) {
    if (error.status !== 401) $("#service").textContent = `unreachable: ${error.message}`;
  }
}

async function tick() {
  try {
    await refreshVehicles();
    // A run started elsewhere (another operator, the API) holds a vehicle: list it.
    const known = new Set(state.runs.filter((r) => LIVE.includes(r.status)).map((r) => r.id));
    const held = state.vehicles.some((v) => v.run && !known.has(v.run));
    if (held || ++state.ticks % 5 === 0) await refreshRuns();
  } catch (error) {
    // The next tick tries again.
  }
  setTimeout(tick, 1000);
}

refresh().then(() => setTimeout(tick, 1000));
