// Penelope's page: the naming tree, object forms, lifecycle, experiments and live plots, all
// through the JSON endpoints and the live WebSocket of `penelope web`.
//
// Readiness markers for people and tests alike: <body data-tree-loaded> once the tree has been
// read, <body data-kinds-loaded> once the kinds have; #live[data-samples] counts plotted samples.
"use strict";

const TREE_PERIOD_MS = 1000;

/** The method words of `penelope ctl call`, by class (every object also has the lifecycle). */
const METHODS = {
  robot: ["joint-positions", "joint-velocities", "operational", "tool-wrench", "fk", "jacobian",
    "ik", "tau", "gravity", "inertia", "named-pose", "go-to", "map-joints"],
  board: ["axis-count", "read-encoders", "amplifiers-enabled", "rearm"],
  sensor: ["read", "bias", "set-probe", "measure", "stream"],
  controller: ["status", "set-robot", "set-trajectory", "set-sensor", "set-gains", "estop", "rearm"],
  trajectory: ["reference", "duration"],
};
const EVERY_OBJECT = ["describe", "configure", "activate", "deactivate", "cleanup", "shutdown", "reset"];
const METHOD_HELP = {
  "fk": "Q: six joint values in rad, or nest|start|work; empty: measured",
  "ik": "X Y Z [NX NY NZ OX OY OZ [AX AY AZ]] (m)",
  "named-pose": "nest | start | work",
  "go-to": "POSE SECONDS, e.g. work 2.0",
  "map-joints": "BOARD J:A ..., e.g. sim0 0:0 1:1 2:2 3:3 4:4 5:5",
  "set-robot": "the robot's name on the node",
  "set-trajectory": "the trajectory's name on the node",
  "set-sensor": "the sensor's name or naming path",
  "set-gains": "TOML, e.g. kp = [100, 100, 100, 10, 10, 10]",
  "reference": "T (s after the start)",
  "set-probe": "X Y Z [VX VY VZ]",
  "measure": "X Y Z [VX VY VZ]",
  "tau": "FX FY FZ TX TY TZ [Q]",
};

const $ = (id) => document.getElementById(id);
const state = { selected: null, tree: [], kinds: [], treeText: "", live: null, plots: null, lastT: null };

/** Shows `text` in the message bar; `error` gives it the error look and its kind. */
function say(text, error) {
  const m = $("message");
  m.textContent = text;
  m.className = error ? "error" : "ok";
  m.dataset.kind = error ? error : "";
}

/** A JSON request; throws an Error with `.kind` for an error answer. */
async function api(method, url, body) {
  const init = { method: method, headers: {}, credentials: "same-origin" };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const response = await fetch(url, init);
  let value = null;
  try { value = await response.json(); } catch (_) { /* not JSON */ }
  if (response.status === 401) {
    window.location.href = "/login";
  }
  if (!response.ok) {
    const e = new Error(value && value.error ? value.error.message : `HTTP ${response.status}`);
    e.kind = value && value.error ? value.error.kind : "http";
    throw e;
  }
  return value;
}

/** Runs `f`, showing its error on the page rather than losing it. */
async function guarded(f) {
  try { return await f(); } catch (e) { say(`${e.kind || "error"}: ${e.message}`, e.kind || "error"); }
}

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") e.className = v; else if (k.startsWith("data-")) e.setAttribute(k, v); else e[k] = v;
  }
  for (const c of children) e.append(c);
  return e;
}

// ---- the naming tree ---------------------------------------------------------------------

async function refreshTree() {
  try {
    const tree = await api("GET", "/api/tree");
    $("naming").textContent = `naming service ${tree.naming}`;
    const text = JSON.stringify(tree.entries);
    if (text !== state.treeText) {
      state.treeText = text;
      state.tree = tree.entries;
      drawTree();
      if (state.selected) showSelected();
    }
    $("tree-age").textContent = "";
    if (!document.body.dataset.treeLoaded) {
      // When the page became usable, ms after navigation started (`scripts/bench-web` reads it).
      document.body.dataset.treeLoadedMs = performance.now().toFixed(1);
      document.body.dataset.treeLoaded = "true";
    }
  } catch (e) {
    $("tree-age").textContent = `(stale: ${e.message})`;
  }
  setTimeout(refreshTree, TREE_PERIOD_MS);
}

function drawTree() {
  const ul = $("tree");
  ul.replaceChildren();
  for (const e of state.tree) {
    const indent = "\u00a0\u00a0".repeat(e.depth);
    if (e.context) {
      ul.append(el("li", { class: "context", "data-path": e.path }, `${indent}${e.name}/`));
      continue;
    }
    const li = el("li", { class: "object", "data-path": e.path, "data-state": e.state || "" },
      el("span", {}, `${indent}${e.name}`), el("span", { class: "kind" }, e.kind));
    if (e.state) li.append(el("span", { class: `state state-${e.state}` }, e.state));
    if (e.class === "creator") li.classList.remove("object");
    else li.addEventListener("click", () => select(e.path));
    if (e.path === state.selected) li.classList.add("selected");
    ul.append(li);
  }
  const nodes = [...new Set(state.tree.filter((e) => e.class === "creator").map((e) => e.node))];
  for (const id of ["create-node", "system-node"]) fillSelect($(id), nodes);
}

function fillSelect(select, values) {
  const now = [...select.options].map((o) => o.value).join("\n");
  if (now === values.join("\n")) return;
  const keep = select.value;
  select.replaceChildren(...values.map((v) => el("option", { value: v }, v)));
  if (values.includes(keep)) select.value = keep;
  select.dispatchEvent(new Event("change"));
}

// ---- one object --------------------------------------------------------------------------

function entryOf(path) {
  return state.tree.find((e) => e.path === path && !e.context);
}

function select(path) {
  state.selected = path;
  for (const li of $("tree").children) li.classList.toggle("selected", li.dataset.path === path);
  const entry = entryOf(path);
  const methods = EVERY_OBJECT.concat(METHODS[entry ? entry.class : ""] || []);
  const m = $("method-name");
  m.replaceChildren(...methods.map((w) => el("option", { value: w }, w)));
  m.value = methods.length > EVERY_OBJECT.length ? methods[EVERY_OBJECT.length] : "describe";
  m.dispatchEvent(new Event("change"));
  $("method-result").textContent = "";
  showSelected();
}

function showSelected() {
  const entry = entryOf(state.selected);
  $("selected-path").textContent = state.selected || "";
  $("object-panel").classList.toggle("hidden", !entry);
  if (!entry) return;
  $("selected-kind").textContent = `${entry.kind} (${entry.class}) on node ${entry.node}`;
  $("selected-state").textContent = entry.state;
  $("watch").disabled = !(entry.class === "controller" || entry.class === "robot");
  guarded(async () => {
    const d = await api("GET", `/api/object?path=${encodeURIComponent(state.selected)}`);
    const info = d.object && d.object.Object;
    const rel = $("selected-relations");
    rel.replaceChildren(...(info ? info.relations : []).map(([r, t]) => el("li", {}, `${r}: ${t}`)));
  });
}

async function callMethod(path, method, args) {
  const r = await api("POST", "/api/call", { path: path, method: method, args: args || "" });
  say(`${path} ${method}: ${r.text.split("\n")[0]}`);
  return r;
}

/** The red button: every loop of every node latches its e-stop. */
async function estopAll() {
  const r = await api("POST", "/api/estop", {});
  const parts = r.nodes.map((n) =>
    `${n.node}: ${n.stopped.length} stopped${n.stopped.length ? ` (${n.stopped.join(", ")})` : ""}` +
    `${n.pending.length ? `, not yet ticked: ${n.pending.join(", ")}` : ""}`);
  say(`E-STOP: ${parts.join("; ") || "no node"}`);
  return r;
}

// ---- creating objects --------------------------------------------------------------------

async function loadKinds() {
  const k = await api("GET", "/api/kinds");
  state.kinds = k.nodes;
  drawKinds();
  document.body.dataset.kindsLoaded = "true";
}

function drawKinds() {
  const node = state.kinds.find((n) => n.node === $("create-node").value) || state.kinds[0];
  const select = $("create-kind");
  const keep = select.value;
  select.replaceChildren();
  if (!node) return;
  const groups = {};
  for (const k of node.kinds) {
    (groups[k.class] = groups[k.class] || el("optgroup", { label: k.class })).append(
      el("option", { value: k.kind }, k.kind));
  }
  select.append(...Object.values(groups));
  if (node.kinds.some((k) => k.kind === keep)) select.value = keep;
  drawFields();
}

/** The form fields of the chosen kind: one per key, its default as placeholder, unit below. */
function drawFields() {
  const node = state.kinds.find((n) => n.node === $("create-node").value) || state.kinds[0];
  const kind = node && node.kinds.find((k) => k.kind === $("create-kind").value);
  const box = $("create-fields");
  box.replaceChildren();
  $("create-summary").textContent = kind ? kind.summary : "";
  if (!kind) return;
  for (const key of kind.keys) {
    const input = el("input", { placeholder: key.default, title: key.note, "data-key": key.key });
    const label = el("label", {}, el("span", { class: "mono" }, key.key), input);
    if (key.note) label.append(el("span", { class: "note" }, key.note));
    box.append(label);
  }
}

async function create(ev) {
  ev.preventDefault();
  const settings = [...$("create-fields").querySelectorAll("input[data-key]")]
    .filter((i) => i.value.trim() !== "")
    .map((i) => [i.dataset.key, i.value]);
  const r = await api("POST", "/api/create", {
    node: $("create-node").value, kind: $("create-kind").value, name: $("create-name").value,
    settings: settings, config: $("create-config").value,
  });
  say(`created ${r.path} (${r.object.kind}): ${r.object.state}`);
  $("create-name").value = "";
  $("create-config").value = "";
  for (const i of $("create-fields").querySelectorAll("input")) i.value = "";
  state.selected = r.path;
}

// ---- experiments -------------------------------------------------------------------------

async function loadSystems() {
  const s = await api("GET", "/api/systems");
  const select = $("system-file");
  for (const f of s.files) select.append(el("option", { value: f }, f));
}

async function loadSystem(ev) {
  ev.preventDefault();
  say("loading the system file…");
  const r = await api("POST", "/api/system", {
    node: $("system-node").value, file: $("system-file").value, text: $("system-text").value,
  });
  say(`${r.node}: created and started ${r.created.length} objects`);
}

async function record(action) {
  const body = { node: $("system-node").value, action: action, path: $("record-path").value };
  const r = await api("POST", "/api/record", body);
  const link = $("record-download");
  if (action === "start") {
    say(`${r.node}: recording ${r.controllers.join(", ")} to ${r.path}`);
    link.classList.add("hidden");
  } else {
    say(`${r.node}: recorded ${r.ticks} control ticks to ${r.path}`);
    link.href = `/api/recording?path=${encodeURIComponent(r.path)}`;
    link.download = r.path.split("/").pop();
    link.classList.remove("hidden");
  }
}

// ---- live --------------------------------------------------------------------------------

function watch(path) {
  if (state.live) state.live.close();
  if (!state.plots) state.plots = makePlots();
  for (const p of Object.values(state.plots)) p.clear();
  state.lastT = null;
  const live = $("live");
  live.dataset.samples = "0";
  live.dataset.path = path;
  const scheme = window.location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${scheme}://${window.location.host}/api/live?path=${encodeURIComponent(path)}`);
  state.live = ws;
  $("live-label").textContent = `watching ${path}`;
  $("rearm").disabled = false;
  ws.onmessage = (m) => onLive(JSON.parse(m.data));
  ws.onclose = () => {
    if (state.live === ws) $("live-label").textContent = `stopped watching ${path}`;
  };
}

function onLive(msg) {
  const live = $("live");
  if (msg.type === "batch") {
    for (const r of msg.records) {
      state.plots.q.push(r.t, r.q);
      state.plots.p.push(r.t, r.p);
      state.plots.f.push(r.t, r.f);
      if (state.lastT !== null) state.plots.dt.push(r.t, [(r.t - state.lastT) * 1000]);
      state.lastT = r.t;
      live.dataset.state = r.s;
    }
    live.dataset.samples = String(Number(live.dataset.samples) + msg.records.length);
    live.dataset.batches = String(Number(live.dataset.batches) + 1);
    requestAnimationFrame(() => { for (const p of Object.values(state.plots)) p.draw(); });
  } else if (msg.type === "event") {
    const bad = ["estop", "fault", "holding"].includes(msg.to);
    const text = `t ${msg.t.toFixed(3)} s  ${msg.from} → ${msg.to}${msg.fault ? `  (${msg.fault})` : ""}`;
    $("events").prepend(el("li", { class: bad ? "bad" : "good", "data-to": msg.to }, text));
  } else if (msg.type === "status") {
    $("live-counters").textContent =
      `ticks ${msg.ticks} · overruns ${msg.overruns} · telemetry dropped ${msg.telemetry_dropped}`;
    live.dataset.overruns = String(msg.overruns);
  } else if (msg.type === "error") {
    say(`${msg.error.kind}: ${msg.error.message}`, msg.error.kind);
  }
}

// ---- wiring ------------------------------------------------------------------------------

function init() {
  $("record-path").value = `penelope-run-${new Date().toISOString().replace(/[:.]/g, "-")}.mcap`;
  $("create-node").addEventListener("change", drawKinds);
  $("create-kind").addEventListener("change", drawFields);
  $("create-form").addEventListener("submit", (ev) => guarded(() => create(ev)));
  $("system-form").addEventListener("submit", (ev) => guarded(() => loadSystem(ev)));
  $("record-start").addEventListener("click", () => guarded(() => record("start")));
  $("record-stop").addEventListener("click", () => guarded(() => record("stop")));
  $("method-name").addEventListener("change", () => {
    $("method-help").textContent = METHOD_HELP[$("method-name").value] || "";
  });
  $("method-form").addEventListener("submit", (ev) => {
    ev.preventDefault();
    guarded(async () => {
      const r = await callMethod(state.selected, $("method-name").value, $("method-args").value);
      $("method-result").textContent = r.text;
    });
  });
  for (const b of document.querySelectorAll("button[data-transition]")) {
    b.addEventListener("click", () => guarded(() => callMethod(state.selected, b.dataset.transition)));
  }
  $("destroy").addEventListener("click", () => guarded(async () => {
    const r = await api("POST", "/api/destroy", { path: state.selected, force: $("destroy-force").checked });
    say(`destroyed ${r.destroyed}`);
  }));
  $("watch").addEventListener("click", () => watch(state.selected));
  $("estop").addEventListener("click", () => guarded(estopAll));
  $("rearm").addEventListener("click", () => guarded(() => callMethod($("live").dataset.path, "rearm")));
  refreshTree();
  guarded(loadKinds);
  guarded(loadSystems);
}

document.addEventListener("DOMContentLoaded", init);
