// The page's 3D view: every robot of the system drawn from its description (a URDF, through
// urdf-loader) at its live joint positions, side by side; the contact shapes of the simulated
// world each robot touches; the sensed wrench and the master's displayed force as arrows; the
// slaves' tool traces. And the teleoperation panel of a channel.
//
// Data: `/api/tree` (which robots and channels there are), `/api/robot?path=` (a robot's
// description), one `/api/live?path=ROBOT` socket per robot (its driving loop's telemetry),
// `/api/object?path=` and `/api/teleop?path=` for the panel.
//
// Test hook and readiness markers: `window.penelopeScene` (robots(), jointAngles(path),
// setVisible(path, on), render()); #scene3d[data-robots] counts robots drawn,
// #scene3d[data-frames] telemetry samples drawn.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import URDFLoader from "urdf-loader";

const TREE_PERIOD_MS = 2000;
const TELEOP_PERIOD_MS = 1000;
/** Robots side by side along world y, this far apart (the scene crate's placement). */
const SPACING_M = 1.0;
/** Tool positions kept in a trace. */
const TRACE_POINTS = 1500;
/** Arrow length per newton (capped). */
const ARROW_M_PER_N = 0.02;
const ARROW_MAX_M = 0.4;
/** Samples per second the 3D view asks of a loop (decimation of a 1 kHz loop). */
const LIVE_DECIMATION = 10;

const view = { robots: new Map(), channels: [], renderer: null, dirty: true, order: [] };

function $(id) { return document.getElementById(id); }

async function getJson(url) {
  const r = await fetch(url, { credentials: "same-origin" });
  let v = null;
  try { v = await r.json(); } catch (_) { /* not JSON */ }
  if (!r.ok) {
    const e = new Error(v && v.error ? v.error.message : `HTTP ${r.status}`);
    e.kind = v && v.error ? v.error.kind : "http";
    throw e;
  }
  return v;
}

// ---- the scene ---------------------------------------------------------------------------

function makeScene() {
  const box = $("scene3d");
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  } catch (e) {
    $("scene-label").textContent = `(no WebGL in this browser: ${e.message})`;
    box.dataset.error = "no-webgl";
    return false;
  }
  renderer.setPixelRatio(1);
  renderer.setSize(box.clientWidth, box.clientHeight);
  renderer.setClearColor(0xe9eef4);
  box.append(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(45, box.clientWidth / box.clientHeight, 0.01, 50);
  camera.up.set(0, 0, 1);
  camera.position.set(1.3, -0.45, 0.8);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(0.2, 0.5, 0.15);
  controls.update();
  controls.addEventListener("change", () => { view.dirty = true; });
  // Once someone turns the view, it stays theirs: no more framing by the page.
  controls.addEventListener("start", () => { view.userMoved = true; });
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8090a0, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(2, -3, 4);
  scene.add(sun);
  const grid = new THREE.GridHelper(4, 20, 0x9aa7b8, 0xc9d2dd);
  grid.rotation.x = Math.PI / 2; // the grid in the x-y plane: z is up
  scene.add(grid);
  scene.add(new THREE.AxesHelper(0.2));
  Object.assign(view, { renderer, scene, camera, controls, box });
  new ResizeObserver(() => {
    if (!box.clientWidth) return;
    renderer.setSize(box.clientWidth, box.clientHeight);
    camera.aspect = box.clientWidth / box.clientHeight;
    camera.updateProjectionMatrix();
    view.dirty = true;
  }).observe(box);
  const frame = () => {
    if (view.dirty) {
      view.dirty = false;
      renderer.render(scene, camera);
      placeLabels();
    }
    requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
  return true;
}

/** Points the camera at every robot drawn, from the front right and above, far enough to
 * see them all (until someone turns the view). */
function frameAll() {
  if (view.userMoved) return;
  const box = new THREE.Box3();
  for (const r of view.robots.values()) if (r.model) box.expandByObject(r.model);
  if (box.isEmpty()) return;
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  const fov = (view.camera.fov * Math.PI) / 180;
  const distance = (1.15 * sphere.radius) / Math.sin(Math.min(fov, fov * view.camera.aspect) / 2);
  const from = new THREE.Vector3(1.0, -0.75, 0.55).normalize().multiplyScalar(distance);
  view.controls.target.copy(sphere.center);
  view.camera.position.copy(sphere.center).add(from);
  view.controls.update();
  view.dirty = true;
}

/** Each robot's name under its base, where the camera sees it. */
function placeLabels() {
  const w = view.box.clientWidth;
  const h = view.box.clientHeight;
  for (const r of view.robots.values()) {
    if (!r.group || !r.label) continue;
    const at = new THREE.Vector3(0, 0, -0.06).add(r.group.position).project(view.camera);
    r.label.hidden = !r.group.visible || at.z > 1;
    r.label.style.left = `${((at.x + 1) / 2) * w - 20}px`;
    r.label.style.top = `${((1 - at.y) / 2) * h}px`;
  }
}

/** A contact shape (root frame of its robot) as a mesh. */
function shapeMesh(shape) {
  const material = new THREE.MeshStandardMaterial({
    color: 0x8d6e63, transparent: true, opacity: 0.45, side: THREE.DoubleSide,
  });
  if (shape.kind === "plane") {
    const mesh = new THREE.Mesh(new THREE.PlaneGeometry(0.6, 0.6), material);
    const normal = new THREE.Vector3(...shape.normal).normalize();
    mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), normal);
    mesh.position.set(...shape.point);
    return mesh;
  }
  if (shape.kind === "sphere") {
    const mesh = new THREE.Mesh(new THREE.SphereGeometry(shape.radius, 24, 16), material);
    mesh.position.set(...shape.center);
    return mesh;
  }
  return null;
}

function arrow(color) {
  const a = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 0.1, color, 0.04, 0.025);
  a.visible = false;
  return a;
}

/** Points the arrow `a` at `from` along `force` (N); hidden below half a newton (a sensor's
 * noise). */
function setArrow(a, from, force) {
  const f = new THREE.Vector3(force[0], force[1], force[2]);
  const n = f.length();
  a.visible = n > 0.5;
  if (!a.visible) return;
  a.position.set(from[0], from[1], from[2]);
  a.setDirection(f.divideScalar(n));
  a.setLength(Math.min(ARROW_MAX_M, n * ARROW_M_PER_N), 0.04, 0.025);
}

function traceLine() {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(TRACE_POINTS * 3), 3));
  geometry.setDrawRange(0, 0);
  const line = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: 0x2ca02c }));
  line.frustumCulled = false;
  line.userData.count = 0;
  return line;
}

function pushTrace(line, p) {
  const attr = line.geometry.getAttribute("position");
  const a = attr.array;
  let n = line.userData.count;
  if (n === TRACE_POINTS) {
    a.copyWithin(0, 3);
    n -= 1;
  }
  a[3 * n] = p[0]; a[3 * n + 1] = p[1]; a[3 * n + 2] = p[2];
  line.userData.count = n + 1;
  line.geometry.setDrawRange(0, n + 1);
  attr.needsUpdate = true;
}

// ---- robots ------------------------------------------------------------------------------

/** A robot entry of the tree: its description loaded, drawn, and fed live. */
async function addRobot(entry) {
  const r = { path: entry.path, entry, model: null, joints: [], seq: null, q: null, socket: null };
  view.robots.set(entry.path, r);
  if (!view.scene) return; // no WebGL: said in the label
  try {
    const d = await getJson(`/api/robot?path=${encodeURIComponent(entry.path)}`);
    const loader = new URDFLoader();
    // The page serves no mesh files: a mesh of a URDF is left out (its primitives are drawn).
    loader.loadMeshCb = (path, _manager, _material, done) => done(null, new Error(`${path}: no meshes served`));
    loader.parseCollision = false;
    const model = loader.parse(d.urdf);
    // The measured joints are drawn as they are, also beyond the URDF's limits.
    for (const j of Object.values(model.joints)) j.ignoreLimits = true;
    r.model = model;
    r.joints = d.joint_names;
    r.description = d;
    const group = new THREE.Group();
    group.name = entry.path;
    group.add(model);
    for (const shape of d.contacts) {
      const m = shapeMesh(shape);
      if (m) group.add(m);
    }
    r.wrench = arrow(0xd62728);
    r.display = arrow(0xff7f0e);
    r.trace = traceLine();
    group.add(r.wrench, r.display, r.trace);
    r.group = group;
    r.label = Object.assign(document.createElement("span"), { className: "robot-label", textContent: entry.object });
    view.box.append(r.label);
    view.scene.add(group);
    place();
    follow(r);
    $("scene3d").dataset.robots = String([...view.robots.values()].filter((x) => x.model).length);
    view.dirty = true;
  } catch (e) {
    r.error = `${e.kind || "error"}: ${e.message}`;
    $("scene-label").textContent = `${entry.path}: ${r.error}`;
  }
}

/** Side by side along world y, 1 m apart, in the order the robots are listed. */
function place() {
  let i = 0;
  for (const path of view.order) {
    const r = view.robots.get(path);
    if (r && r.group) r.group.position.set(0, i * SPACING_M, 0);
    i += 1;
  }
  view.dirty = true;
  if (view.framed !== view.order.join("\n") && view.order.every((p) => view.robots.get(p) && (view.robots.get(p).model || view.robots.get(p).error))) {
    // Framed once every robot listed is drawn (at its first joints), again when they change.
    view.framed = view.order.join("\n");
    for (const r of view.robots.values()) if (r.group) r.group.updateMatrixWorld(true);
    frameAll();
  }
}

function removeRobot(path) {
  const r = view.robots.get(path);
  if (!r) return;
  if (r.socket) { r.closing = true; r.socket.close(); }
  if (r.group) view.scene.remove(r.group);
  if (r.label) r.label.remove();
  view.robots.delete(path);
  view.dirty = true;
}

/** The robot's joints set to `q` (rad or m, in `joint_names` order). */
function setJoints(r, q) {
  for (let i = 0; i < r.joints.length && i < q.length; i++) {
    const j = r.model.joints[r.joints[i]];
    if (j) j.setJointValue(q[i]);
  }
}

/** Follows the loop that drives the robot: one live socket, reopened while the robot exists. */
function follow(r) {
  const scheme = window.location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${scheme}://${window.location.host}/api/live?path=` +
    `${encodeURIComponent(r.path)}&decimation=${LIVE_DECIMATION}`);
  r.socket = ws;
  ws.onmessage = (m) => {
    const msg = JSON.parse(m.data);
    if (msg.type === "batch" && msg.records.length) {
      for (const rec of msg.records) {
        if (isSlave(r.path)) pushTrace(r.trace, rec.p);
      }
      const last = msg.records[msg.records.length - 1];
      setJoints(r, last.q);
      r.seq = last.seq;
      r.q = last.q;
      r.p = last.p;
      r.f = last.f;
      r.state = last.s;
      r.d = last.d;
      r.clutch = last.c;
      r.fBase = sensedInBase(r, last.f);
      setArrow(r.wrench, last.p, r.fBase);
      const box = $("scene3d");
      box.dataset.frames = String(Number(box.dataset.frames) + msg.records.length);
      view.dirty = true;
      showDisplayed();
    } else if (msg.type === "error") {
      // Not driven by a running loop (yet): shown where it is, retried below.
      r.idle = msg.error.message;
      pollJoints(r);
    }
  };
  ws.onclose = () => {
    if (r.closing || !view.robots.has(r.path)) return;
    setTimeout(() => { if (view.robots.get(r.path) === r) follow(r); }, TREE_PERIOD_MS);
  };
}

/** The sensed force in the robot's base frame. A loop's telemetry carries the wrench as its
 * sensor reports it: a wrist sensor (the simulated one, a Net F/T at the flange) in its own
 * frame, which turns with the tool; that frame's rotation is taken as the drawn tool frame's
 * (a sensor mounted with a rotation of its own would be drawn turned by it). */
function sensedInBase(r, f) {
  const tool = r.model.links[r.description.frames[r.description.frames.length - 1]];
  const v = new THREE.Vector3(f[0], f[1], f[2]);
  if (!tool) return [v.x, v.y, v.z];
  r.group.updateMatrixWorld(true);
  v.applyQuaternion(tool.getWorldQuaternion(new THREE.Quaternion()));
  return [v.x, v.y, v.z];
}

/** A robot no loop drives: its measured joints, read once per retry. */
async function pollJoints(r) {
  try {
    const reply = await fetch("/api/call", {
      method: "POST", credentials: "same-origin", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ path: r.path, method: "joint-positions", args: "" }),
    }).then((x) => x.json());
    const q = reply.reply && reply.reply.Joints;
    if (q) { setJoints(r, q); r.q = q; r.seq = null; view.dirty = true; }
  } catch (_) { /* shown by the tree */ }
}

// ---- channels: who is master, who is slave, the displayed force --------------------------

/** Whether `path` is the slave of a channel (its tool leaves a trace); with no channel in the
 * system, every robot is. */
function isSlave(path) {
  return (view.teleop || []).length === 0 || view.channels.some((c) => c.slavePath === path);
}

/** `scale 1 force_gain 0.5 torque_gain 1 rotation_rpy_deg 0 0 0` as numbers. */
function parseMapping(text) {
  const w = text.split(/\s+/);
  const at = (k) => Number(w[w.indexOf(k) + 1]);
  const i = w.indexOf("rotation_rpy_deg");
  return {
    scale: at("scale"), forceGain: at("force_gain"), torqueGain: at("torque_gain"),
    rpyDeg: i >= 0 ? [Number(w[i + 1]), Number(w[i + 2]), Number(w[i + 3])] : [0, 0, 0],
  };
}

/** The master's displayed force: the wrench its loop commanded after its caps (what its
 * motors produce at the handle), in its base frame as the tick carries it, drawn at its tool. */
function showDisplayed() {
  for (const c of view.channels) {
    const master = view.robots.get(c.masterPath);
    if (!master || !master.display || !master.p || !master.d) continue;
    setArrow(master.display, master.p, master.d);
    master.displayed = master.d;
  }
}

// ---- the teleoperation panel ---------------------------------------------------------------

/** The law a channel runs, by the kinds of its active controllers. */
const LAWS = {
  "controller/force-display": "position forward, force back",
  "controller/position-error-master": "position error",
  "controller/wave-master": "wave variables",
  "controller/four-channel-master": "four-channel",
};

function row(name, value, cls) {
  const tr = document.createElement("tr");
  const a = document.createElement("td");
  const b = document.createElement("td");
  a.textContent = name;
  b.textContent = value;
  if (cls) b.className = cls;
  tr.dataset.row = name;
  tr.append(a, b);
  return tr;
}

/** Reads the chosen channel and its controllers, and fills the panel. */
async function refreshTeleop() {
  const select = $("teleop-channel");
  const paths = (view.teleop || []).map((e) => e.path);
  if ([...select.options].map((o) => o.value).join("\n") !== paths.join("\n")) {
    const keep = select.value;
    select.replaceChildren(...paths.map((p) => Object.assign(document.createElement("option"), { value: p, textContent: p })));
    if (paths.includes(keep)) select.value = keep;
  }
  const path = select.value;
  const body = $("teleop-table").tBodies[0];
  try {
    const channels = [];
    for (const e of view.teleop || []) {
      const d = await getJson(`/api/object?path=${encodeURIComponent(e.path)}`);
      const rel = Object.fromEntries((d.object.Object || { relations: [] }).relations);
      const base = e.path.slice(0, e.path.lastIndexOf("/trajectories/"));
      channels.push({
        path: e.path, entry: e, relations: rel,
        masterPath: `${base}/robots/${rel.master}`, slavePath: `${base}/robots/${rel.slave}`,
        mapping: rel.mapping ? parseMapping(rel.mapping) : null,
      });
    }
    view.channels = channels;
    const c = channels.find((x) => x.path === path);
    if (!c) { body.replaceChildren(); $("teleop-note").textContent = paths.length ? "" : "no teleoperation channel"; return; }
    // Its controllers: those on its node whose trajectory it is.
    const controllers = (view.tree || []).filter((e) => !e.context && e.class === "controller" && e.node === c.entry.node);
    const halves = [];
    for (const e of controllers) {
      const d = await getJson(`/api/object?path=${encodeURIComponent(e.path)}`);
      const rel = Object.fromEntries((d.object.Object || { relations: [] }).relations);
      if (rel.trajectory !== c.entry.object) continue;
      halves.push({ entry: e, status: d.status && d.status.Status });
    }
    const active = halves.filter((h) => h.entry.state === "active");
    const law = active.map((h) => LAWS[h.entry.kind]).filter(Boolean);
    const rows = [
      row("master → slave", `${c.relations.master} → ${c.relations.slave}`),
      row("law", law.length ? law.join(", ") : active.length ? active.map((h) => h.entry.kind).join(", ") : "none active"),
    ];
    if (c.mapping) {
      rows.push(row("scale", `${c.mapping.scale} (slave motion per master motion)`));
      rows.push(row("force gain", `${c.mapping.forceGain} (displayed per sensed force)`));
    }
    for (const h of active) {
      const s = h.status;
      const state = s && s.last ? s.last.state : "no tick yet";
      const bad = ["estop", "fault", "faulted", "holding"].includes(state);
      rows.push(row(h.entry.object, `${h.entry.kind.split("/")[1]}: ${state}` +
        (s ? ` · ${s.ticks} ticks · ${s.overruns} overruns` : ""), bad ? "bad" : "good"));
    }
    // Link health: a channel linked to another node says how its link is; else it is local.
    if (c.relations.link) rows.push(row("link", c.relations.link, /down|lost/.test(c.relations.link) ? "bad" : "good"));
    else if (c.relations.zenoh) rows.push(row("link", c.relations.zenoh));
    else rows.push(row("link", "both ends on this node (no network link)", "good"));
    const master = view.robots.get(c.masterPath);
    if (master && master.displayed) {
      const n = Math.hypot(...master.displayed);
      rows.push(row("displayed force", `${n.toFixed(2)} N (what the master's motors produce)`));
    }
    if (master && master.clutch !== undefined) {
      rows.push(row("clutch", master.clutch === null ? "no hand holds the master"
        : master.clutch ? "held: the slave follows" : "released: the slave holds",
        master.clutch === false ? "bad" : "good"));
    }
    // The energy observers of the laws that have them (J; negative: energy given out that
    // never entered), from each half's newest tick.
    for (const h of active) {
      const last = h.status && h.status.last;
      if (!last) continue;
      const e = [["port", last.port_energy], ["channel", last.channel_energy]]
        .filter(([, v]) => v !== null && v !== undefined);
      if (e.length) {
        rows.push(row(`${h.entry.object} energy`, e.map(([k, v]) => `${k} ${v.toFixed(3)} J`).join(" · "),
          e.some(([, v]) => v < 0) ? "bad" : "good"));
      }
    }
    body.replaceChildren(...rows);
    $("teleop-note").textContent = "";
    $("teleop-panel").dataset.channel = c.path;
  } catch (e) {
    $("teleop-note").textContent = `(stale: ${e.message})`;
  }
}

async function teleopLoop() {
  await refreshTeleop();
  setTimeout(teleopLoop, TELEOP_PERIOD_MS);
}

// ---- the tree: which robots ----------------------------------------------------------------

async function refresh() {
  try {
    const tree = await getJson("/api/tree");
    const robots = tree.entries.filter((e) => !e.context && e.class === "robot");
    view.order = robots.map((e) => e.path);
    for (const e of robots) if (!view.robots.has(e.path)) addRobot(e);
    for (const path of [...view.robots.keys()]) if (!view.order.includes(path)) removeRobot(path);
    place();
    view.tree = tree.entries;
    view.teleop = tree.entries.filter((e) => !e.context && e.kind === "trajectory/teleop");
    $("scene-label").textContent = robots.length ? "" : "(no robots)";
  } catch (e) {
    $("scene-label").textContent = `(stale: ${e.message})`;
  }
  setTimeout(refresh, TREE_PERIOD_MS);
}

// ---- the test hook -------------------------------------------------------------------------

window.penelopeScene = {
  /** The robots drawn, by naming path. */
  robots: () => [...view.robots.values()].filter((r) => r.model).map((r) => r.path),
  /** The joint values the scene holds for `path` (read back from the drawn model), the
   * sequence number of the telemetry sample they came from, where the drawn model puts the
   * tool (base frame, m), the sample's wrench (as its sensor reports it), the sensed force
   * drawn (base frame) and, for a master, the displayed force drawn. */
  jointAngles: (path) => {
    const r = view.robots.get(path);
    if (!r || !r.model) return null;
    // Where the drawn model puts its last frame (the tool), in the robot's base frame.
    const tool = r.model.links[r.description.frames[r.description.frames.length - 1]];
    let at = null;
    if (tool) {
      r.group.updateMatrixWorld(true);
      const p = r.group.worldToLocal(tool.getWorldPosition(new THREE.Vector3()));
      at = [p.x, p.y, p.z];
    }
    return {
      seq: r.seq, q: r.joints.map((n) => r.model.joints[n].angle), tool: at, f: r.f,
      forceInBase: r.fBase || null, displayed: r.displayed || null,
    };
  },
  /** Shows or hides a robot (and its arrows and trace). */
  setVisible: (path, on) => {
    const r = view.robots.get(path);
    if (r && r.group) { r.group.visible = on; view.dirty = true; }
  },
  /** Renders now (a test's screenshot then shows this state). */
  render: () => { if (view.renderer) view.renderer.render(view.scene, view.camera); },
};

$("teleop-channel").addEventListener("change", refreshTeleop);
makeScene();
refresh();
teleopLoop();
