// The camera panel: a camera's frames live, each with the force and pose sample measured at its
// capture instant (from `penelope web`'s /api/camera socket), the force drawn as an arrow at the
// tool, how far the video is behind the hand, and a plot of the force with the frames' capture
// instants marked. Only this view is ever delayed: the haptic display never is.
//
// Readiness markers for tests: #camera-canvas[data-frames] counts frames drawn,
// [data-arrow] is "1" when the last frame carried a force arrow ([data-force-n] its newtons), [data-skew-ms] the operator's
// skew, [data-aligned-skew-ms] the drawn sample's residual skew.
"use strict";

const CAMERA_TREE_PERIOD_MS = 2000;
const CAMERA_PLOT_SECONDS = 4;
const CAM = { ws: null, path: null, meta: null, pending: null, drawing: false, forces: [], captures: [] };

const camEl = (id) => document.getElementById(id);

/** The cameras of the naming tree (sensors whose kind is a camera). */
async function cameraRefresh() {
  try {
    const r = await fetch("/api/tree", { credentials: "same-origin" });
    if (r.ok) {
      const tree = await r.json();
      const cameras = tree.entries.filter((e) => e.class === "sensor" && /camera/.test(e.kind || ""));
      const select = camEl("camera-select");
      const paths = cameras.map((c) => c.path);
      if (JSON.stringify(paths) !== select.dataset.paths) {
        select.dataset.paths = JSON.stringify(paths);
        select.replaceChildren(...paths.map((p) => new Option(p, p)));
        if (CAM.path) select.value = CAM.path;
      }
      // The first configured camera is watched by itself, as the 3D view shows its robots (a
      // camera streams once configured: it has no loop to activate).
      const running = cameras.find((c) => c.state === "active" || c.state === "inactive");
      if (!CAM.ws && running) cameraWatch(running.path);
      camEl("camera-label").textContent = cameras.length ? "" : "(no camera in the system)";
    }
  } catch (e) {
    camEl("camera-label").textContent = `(tree: ${e.message})`;
  }
  setTimeout(cameraRefresh, CAMERA_TREE_PERIOD_MS);
}

function cameraWatch(path) {
  if (CAM.ws) CAM.ws.close();
  CAM.path = path;
  CAM.forces = [];
  CAM.captures = [];
  CAM.meta = null;
  const canvas = camEl("camera-canvas");
  canvas.dataset.frames = "0";
  const scheme = window.location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${scheme}://${window.location.host}/api/camera?path=${encodeURIComponent(path)}`);
  ws.binaryType = "blob";
  CAM.ws = ws;
  camEl("camera-label").textContent = `watching ${path}`;
  ws.onmessage = (m) => {
    if (typeof m.data === "string") cameraMessage(JSON.parse(m.data));
    else if (CAM.meta) {
      // A frame's image follows its description; a browser busy drawing skips frames.
      const meta = CAM.meta;
      CAM.meta = null;
      if (!CAM.drawing) {
        CAM.drawing = true;
        createImageBitmap(m.data).then((bitmap) => {
          cameraDraw(meta, bitmap);
          bitmap.close();
        }).finally(() => { CAM.drawing = false; });
      }
    }
  };
  ws.onclose = () => {
    if (CAM.ws === ws) {
      CAM.ws = null;
      camEl("camera-label").textContent = `stopped watching ${path}`;
    }
  };
}

function cameraMessage(msg) {
  if (msg.type === "frame") {
    CAM.meta = msg;
    for (const r of msg.recent) CAM.forces.push(r);
    CAM.captures.push([msg.t, msg.aligned ? Math.hypot(...msg.aligned.f) : null]);
    const horizon = msg.t - CAMERA_PLOT_SECONDS - 1;
    while (CAM.forces.length && CAM.forces[0][0] < horizon) CAM.forces.shift();
    while (CAM.captures.length && CAM.captures[0][0] < horizon) CAM.captures.shift();
  } else if (msg.type === "subscribed") {
    camEl("camera-label").textContent = `${msg.path} watching ${msg.robot}`;
  } else if (msg.type === "error") {
    camEl("camera-label").textContent = `${msg.error.kind}: ${msg.error.message}`;
  }
}

function fmtMs(v) {
  return v === null || v === undefined ? "–" : `${v.toFixed(1)} ms`;
}

function cameraDraw(meta, bitmap) {
  const canvas = camEl("camera-canvas");
  if (canvas.width !== meta.width || canvas.height !== meta.height) {
    canvas.width = meta.width;
    canvas.height = meta.height;
  }
  const g = canvas.getContext("2d");
  g.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  const aligned = camEl("camera-align").checked;
  const sample = aligned ? meta.aligned : meta.newest;
  const scale = canvas.width / 640;
  if (sample && sample.arrow) {
    const [x0, y0] = sample.arrow.tool;
    const [x1, y1] = sample.arrow.tip;
    g.strokeStyle = "#ffd400";
    g.fillStyle = "#ffd400";
    g.lineWidth = 4 * scale;
    g.beginPath(); g.moveTo(x0, y0); g.lineTo(x1, y1); g.stroke();
    const angle = Math.atan2(y1 - y0, x1 - x0);
    const head = 14 * scale;
    g.beginPath();
    g.moveTo(x1, y1);
    g.lineTo(x1 - head * Math.cos(angle - 0.45), y1 - head * Math.sin(angle - 0.45));
    g.lineTo(x1 - head * Math.cos(angle + 0.45), y1 - head * Math.sin(angle + 0.45));
    g.closePath(); g.fill();
    g.beginPath(); g.arc(x0, y0, 5 * scale, 0, 2 * Math.PI); g.stroke();
    g.font = `${Math.round(16 * scale)}px system-ui, sans-serif`;
    g.lineWidth = 3 * scale;
    g.strokeStyle = "#000a";
    const label = `${sample.arrow.n.toFixed(1)} N`;
    g.strokeText(label, x1 + 8 * scale, y1);
    g.fillText(label, x1 + 8 * scale, y1);
  }
  const f = meta.figures;
  const text = f.text || "no force from the hand yet";
  g.font = `bold ${Math.round(18 * scale)}px system-ui, sans-serif`;
  g.fillStyle = "#0009";
  g.fillRect(0, 0, canvas.width, 30 * scale);
  g.fillStyle = "#fff";
  g.fillText(`${text} · overlay ${aligned ? "at the frame's capture" : "newest (not aligned)"}`, 8 * scale, 21 * scale);
  canvas.dataset.frames = String(Number(canvas.dataset.frames || 0) + 1);
  canvas.dataset.arrow = sample && sample.arrow ? "1" : "0";
  canvas.dataset.forceN = sample && sample.arrow ? sample.arrow.n.toFixed(2) : "";
  canvas.dataset.skewMs = f.operator_skew_ms === null ? "" : f.operator_skew_ms.toFixed(3);
  canvas.dataset.alignedSkewMs = sample ? sample.skew_ms.toFixed(3) : "";
  camEl("camera-skew").textContent = text;
  const s = meta.summary;
  const p = (x) => (x ? `p50 ${fmtMs(x.p50_ms)} · p99 ${fmtMs(x.p99_ms)}` : "–");
  camEl("camera-figures").textContent =
    `frame ${meta.seq} · video latency ${p(s.video_latency)} · force latency ${p(s.force_latency)}` +
    ` · residual skew aligned ${p(s.aligned_skew)}, newest ${p(s.unaligned_skew)}` +
    ` · dropped ${meta.dropped.node} at the node, ${meta.dropped.socket} here`;
  cameraPlot(meta.t);
}

/** Force against time (the last seconds), the frames' capture instants marked. */
function cameraPlot(now) {
  const canvas = camEl("camera-plot");
  const w = canvas.width = canvas.clientWidth || 480;
  const h = canvas.height = 120;
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, w, h);
  const t0 = now - CAMERA_PLOT_SECONDS;
  const visible = CAM.forces.filter((r) => r[0] >= t0);
  let top = 1;
  for (const r of visible) top = Math.max(top, Math.abs(r[1]), Math.abs(r[2]), Math.abs(r[3]), Math.hypot(r[1], r[2], r[3]));
  const x = (t) => 36 + (w - 44) * (t - t0) / CAMERA_PLOT_SECONDS;
  const y = (v) => h / 2 - (h / 2 - 10) * v / top;
  g.strokeStyle = "#ccc"; g.lineWidth = 1;
  g.beginPath(); g.moveTo(36, y(0)); g.lineTo(w - 8, y(0)); g.stroke();
  g.fillStyle = "#6b7686"; g.font = "11px system-ui, sans-serif";
  g.fillText(`${top.toFixed(0)} N`, 2, 12); g.fillText(`-${top.toFixed(0)}`, 2, h - 4);
  const series = [[1, "#1f77b4"], [2, "#d62728"], [3, "#2ca02c"], [4, "#000"]];
  for (const [i, color] of series) {
    g.strokeStyle = color; g.lineWidth = i === 4 ? 1.8 : 1.2;
    g.beginPath();
    visible.forEach((r, k) => {
      const v = i === 4 ? Math.hypot(r[1], r[2], r[3]) : r[i];
      if (k === 0) g.moveTo(x(r[0]), y(v)); else g.lineTo(x(r[0]), y(v));
    });
    g.stroke();
  }
  // Each frame's capture instant: a tick at the top and a dot at the force it is shown with.
  g.fillStyle = "#ff7f0e"; g.strokeStyle = "#ff7f0e";
  for (const [t, n] of CAM.captures) {
    if (t < t0) continue;
    g.beginPath(); g.moveTo(x(t), 0); g.lineTo(x(t), 7); g.stroke();
    if (n !== null) { g.beginPath(); g.arc(x(t), y(n), 2.5, 0, 2 * Math.PI); g.fill(); }
  }
  canvas.dataset.points = String(visible.length);
}

document.addEventListener("DOMContentLoaded", () => {
  camEl("camera-watch").addEventListener("click", () => {
    const path = camEl("camera-select").value;
    if (path) cameraWatch(path);
  });
  cameraRefresh();
});
