// The page of tml serve: missions, runs, vehicles and the live view of a run, all through
// the service's HTTP API (docs/serve.md). Plain script, no build step, nothing fetched
// from anywhere but the service.
"use strict";

const state = {
  token: sessionStorage.getItem("tml-token") || "",
  missions: [], runs: [], vehicles: [],
  chosenMission: null,          // id of the mission chosen in the list
  run: null,                    // the run shown: its JSON from GET /runs/{id}
  outline: null,                // the shown run's mission: tree and world
  plans: {},                    // planned path per vehicle key
  tracks: {},                   // flown track per vehicle id, from the run's telemetry
  stream: null,                 // AbortController of the run's event stream
  messages: {},                 // last autopilot message per vehicle
};
const MAX_LINES = 50;           // events and messages kept in the lists

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

function showUploadErrors(result, error, source) {
  const lines = source.split(/\r?\n/);
  const shown = [element("p", {class: "error", textContent: error.message})];
  for (const found of error.body.diagnostics || []) {
    const where = `line ${found.line}, column ${found.column}`;
    const item = element("div", {class: "diagnostic", "data-line": found.line},
      element("span", {class: found.severity === "error" ? "error" : "",
        textContent: `${where}: ${found.severity} ${found.code}: ${found.message}`}));
    if (found.line >= 1 && found.line <= lines.length) {
      const caret = found.column >= 1 ? "\n" + " ".repeat(found.column - 1) + "^" : "";
      item.append(element("pre", {textContent: lines[found.line - 1] + caret}));
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
  try {
    const run = await api("POST", "/runs", request);
    result.replaceChildren(element("p", {class: "ok", textContent: `run ${run.id} started`}));
    await refreshRuns();
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
  state.runs = await api("GET", "/runs");
  const list = $("#runs");
  list.replaceChildren(...[...state.runs].reverse().map((run) => {
    const item = element("li", {"data-run": run.id,
      class: state.run && state.run.id === run.id ? "chosen" : ""},
      element("span", {textContent: `${run.mission.name} `}),
      element("span", {class: `state state-${stateClass(run.status)}`, textContent: run.status}),
      element("small", {textContent: `run ${run.id} · vehicles ${run.vehicles.join(", ")}`}));
    item.addEventListener("click", () => showRun(run.id));
    return item;
  }));
}

function stateClass(status) {
  return {completed: "done", waiting: "pending", interrupted: "aborted"}[status] || status;
}

async function showRun(runId) {
  if (state.stream) state.stream.abort();
  state.run = await api("GET", `/runs/${runId}`);
  state.tracks = {};
  state.plans = {};
  $("#events").replaceChildren();
  state.outline = null;
  try {
    state.outline = await api("GET", `/missions/${state.run.mission.id}`);
    const report = await api("POST", `/missions/${state.run.mission.id}/verify`,
      {profile: state.run.options.profile || "quadcopter"});
    const plan = [[0, 0, 0]];
    for (const action of report.actions) {
      if (!action.event) plan.push(...action.path);
    }
    state.plans.mission = plan;
  } catch (error) {
    // The mission was deleted since: the run's task states are shown without the tree.
  }
  drawRun();
  await refreshRuns();
  follow(runId);
}

// The run's records as Server-Sent Events, read with fetch so that the token is sent.
async function follow(runId) {
  const controller = new AbortController();
  state.stream = controller;
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
        handleEvent(runId, block);
      }
    }
  } catch (error) {
    // Aborted: another run is shown now.
  }
}

function handleEvent(runId, block) {
  let kind = "message";
  const data = [];
  for (const line of block.split(/\r?\n/)) {
    if (line.startsWith("event:")) kind = line.slice(6).trim();
    else if (line.startsWith("data:")) data.push(line.slice(5).replace(/^ /, ""));
  }
  if (!state.run || state.run.id !== runId || !data.length) return;
  const payload = JSON.parse(data.join("\n"));
  if (kind === "end") {
    state.run = payload;
    drawRun();
    refreshRuns();
  } else if (kind === "record") {
    record(payload);
  }
}

function record(line) {
  const run = state.run;
  const whose = line.vehicle === undefined ? "" : String(line.vehicle);
  if (line.kind === "task" && run.tasks) {
    if (!run.tasks[whose]) run.tasks[whose] = {};
    run.tasks[whose][line.task] = line.state;
    drawTasks();
  } else if (line.kind === "telemetry" && line.position) {
    if (!state.tracks[whose]) state.tracks[whose] = [];
    state.tracks[whose].push([line.position[0], line.position[1]]);
  } else if (line.kind === "mission" && run.status === "waiting") {
    run.status = "running";
    drawRunBar();
  }
  if (["event", "safety", "mission", "error", "vehicle", "control"].includes(line.kind) ||
      (line.kind === "action" && /fail|infeasible/.test(line.message || "")) ||
      (line.kind === "result" && line.ok === false)) {
    addLine($("#events"), line.t, (whose ? `vehicle ${whose}: ` : "") + (line.message || line.kind),
      line.kind);
  }
}

function addLine(list, time, text, kind) {
  list.prepend(element("li", {class: kind ? `kind-${kind}` : ""},
    element("span", {class: "t", textContent: `${Number(time).toFixed(1)} s`}), text));
  while (list.children.length > MAX_LINES) list.lastChild.remove();
}

function drawRun() {
  drawRunBar();
  drawTasks();
  drawTheMap();
}

function drawRunBar() {
  const run = state.run;
  const live = run && ["waiting", "running", "paused"].includes(run.status);
  $("#run-status").textContent = run
    ? `run ${run.id}: ${run.mission.name}: ${run.status}` +
      (run.reason ? ` (${run.reason})` : "") + (run.exit_code !== null ? `, exit ${run.exit_code}` : "")
    : "no run chosen";
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
  const whose = Object.keys(run.tasks).sort();
  const tree = state.outline ? state.outline.tasks : Object.keys(run.tasks[whose[0]] || {}).map(
    (path) => ({name: path, path: path, children: [], on_error: []}));
  const branch = (tasks) => element("ul", {}, ...tasks.map((task) => element("li",
    {"data-task": task.path},
    element("span", {class: "name", textContent: task.name}),
    ...whose.filter((w) => run.tasks[w][task.path] !== undefined).map((w) => {
      const value = run.tasks[w][task.path];
      return element("span", {class: `state state-${value}`, "data-vehicle": w,
        title: w ? `vehicle ${w}` : "no vehicle", textContent: `${w || "·"} ${value}`});
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

function drawTheMap() {
  const shown = state.run ? state.run.vehicles : state.vehicles.map((v) => v.id);
  drawMap($("#map"), {
    world: state.outline ? state.outline.world : {},
    plans: state.plans,
    tracks: state.tracks,
    vehicles: state.vehicles.filter((v) => shown.includes(v.id)),
  });
}

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

$("#pause").addEventListener("click", () => control("pause"));
$("#resume").addEventListener("click", () => control("resume"));
$("#abort").addEventListener("click", () => control("abort"));
// An interrupted run goes on as a new run, which is then shown.
$("#continue").addEventListener("click", async () => {
  const result = $("#control-result");
  try {
    const run = await api("POST", `/runs/${state.run.id}/continue`);
    result.replaceChildren();
    await showRun(run.id);
  } catch (error) {
    result.replaceChildren(element("span", {class: "error", textContent: error.message}));
  }
});
$("#jump").addEventListener("click", () => control("jump", {task: $("#jump-task").value}));

// --- vehicles --------------------------------------------------------------------------------

function drawTelemetry() {
  const body = $("#telemetry tbody");
  const number = (value, digits) => value === null || value === undefined ? "–" : value.toFixed(digits);
  body.replaceChildren(...state.vehicles.map((v) => element("tr", {"data-vehicle": v.id},
    element("td", {textContent: String(v.id), title: v.vehicle_type}),
    element("td", {textContent: v.link}), element("td", {textContent: v.mode}),
    element("td", {textContent: v.armed ? "yes" : "no"}),
    element("td", {textContent: v.position ? v.position[2].toFixed(1) : "–"}),
    element("td", {textContent: number(v.ground_speed, 1)}),
    element("td", {textContent: number(v.heading, 0)}),
    element("td", {textContent: number(v.battery, 0)}),
    element("td", {textContent: v.gps_fix === null ? "–" : String(v.gps_fix)}),
    element("td", {textContent: v.run || ""}))));
  for (const v of state.vehicles) {
    if (v.status_text && state.messages[v.id] !== v.status_text) {
      state.messages[v.id] = v.status_text;
      addLine($("#messages"), v.time, `vehicle ${v.id}: ${v.status_text}`);
    }
  }
}

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
    if (state.run && ["waiting", "running", "paused"].includes(state.run.status)) {
      drawRunBar();
    }
  } catch (error) {
    // The next tick tries again.
  }
  setTimeout(tick, 1000);
}

refresh().then(() => setTimeout(tick, 1000));
