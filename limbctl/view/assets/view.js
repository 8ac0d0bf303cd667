// limbctl live view: draws the pan/tilt plane from the server's WebSocket pushes.
// Two kinds of message: "scene" (samples, region edge loops, hard limits, guide; about 1 Hz)
// and "live" (pose, sample count, teleop cycle, fault; up to 10 Hz). No build step, no CDN.
"use strict";

const COLORS = {
  sample: "#999999",
  region: "rgb(150, 220, 150)",
  traced: "#1a7f1a",
  untraced: "#e08000",
  limits: "#cc2222",
  pose: "#1f5fd0",
  commanded: "#9040c0",
  written: "#000000",
  trail: "rgba(0, 0, 0, 0.35)",
  blocked: "#d01010",
  grid: "#e4e4e4",
  axis: "#b0b0b0",
};
// Degrees of margin around the hard limits (or the data) so markers on the edge stay visible.
const MARGIN_DEG = 5;
// Wait before reconnecting after the server closed or vanished (ms).
const RECONNECT_MS = 1000;
// Written poses kept for the trail: 6 s of the server's 10 Hz pushes.
const TRAIL_LENGTH = 60;
// Which edge of the picture holds the limb, by blocked joint direction (+pan left, tilt up).
const EDGE_WORDS = { "+tilt": "upper", "-tilt": "lower", "+pan": "left", "-pan": "right" };
// Directions as seen from behind the limb, as the terminal names them (left is +pan).
const DIRECTION_NAMES = { "+pan": "left", "-pan": "right", "+tilt": "up", "-tilt": "down" };
// How far (deg) the point must lie beyond the written pose along a pushed direction for it to
// be called blocked: the server's BLOCKED_MIN_DEG (limbctl/teleop/explain.py).
const BLOCKED_MIN_DEG = 0.2;
// The session's keys, when the address carries them: "key" steers, "watch" only watches.
const KEY = new URLSearchParams(location.search).get("key");
const WATCH = new URLSearchParams(location.search).get("watch");
// Letters of a tab's tag (no I or O, which read as 1 and 0).
const TAG_LETTERS = "ABCDEFGHJKLMNPQRSTUVWXYZ";

// How this page was opened: a reload keeps the tab's control; anything else takes it if free.
const NAVIGATION = (performance.getEntriesByType("navigation")[0] || {}).type;

// This tab, as the server and the other tabs name it: a random id and the name it shows
// itself ("tab K7, opened 19:02:13"), kept in sessionStorage so a reload of this tab keeps
// them (and takes control back from its own old connection). Any other load makes new ones:
// a duplicated tab inherits sessionStorage, and must not share the name or take the control.
function tabIdentity() {
  let tab = null;
  if (NAVIGATION === "reload") {
    try { tab = JSON.parse(sessionStorage.getItem("limbctl-tab")); } catch (e) { tab = null; }
  }
  if (!tab || !tab.id || !tab.name) {
    const bytes = crypto.getRandomValues(new Uint8Array(16));
    const id = Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("");
    const tag = TAG_LETTERS[bytes[0] % TAG_LETTERS.length] + String(bytes[1] % 10);
    tab = { id: id, name: `tab ${tag}, opened ${new Date().toTimeString().slice(0, 8)}` };
    try { sessionStorage.setItem("limbctl-tab", JSON.stringify(tab)); } catch (e) { /* private mode */ }
  }
  return tab;
}
const TAB = tabIdentity();

const state = { scene: null, live: null, liveFrames: 0, sceneFrames: 0, trail: [], socket: null, opened: 0 };
const canvas = document.getElementById("plane");
// Layers other assets add (leader.js): draw(ctx, P, live) after the markers, show(live) with
// each live message.
const layers = [];
let ctx = canvas.getContext("2d");
let drawPending = false;

function byId(id) { return document.getElementById(id); }
function fmtPose(p) { return p ? `${p[0].toFixed(1)}, ${p[1].toFixed(1)}` : "-"; }

// The plotted window in degrees: the hard limits when known, else what there is to draw.
function bounds() {
  const s = state.scene;
  if (s && s.limits) {
    return { pan: [s.limits.pan[0] - MARGIN_DEG, s.limits.pan[1] + MARGIN_DEG],
             tilt: [s.limits.tilt[0] - MARGIN_DEG, s.limits.tilt[1] + MARGIN_DEG] };
  }
  const pts = [];
  if (s) { pts.push(...s.samples); s.loops.forEach((l) => pts.push(...l.points)); }
  if (state.live && state.live.pose) pts.push(state.live.pose);
  if (state.live && state.live.leader && state.live.leader.pose) pts.push(state.live.leader.pose);
  if (pts.length === 0) return { pan: [-180, 180], tilt: [-90, 90] };
  const pans = pts.map((p) => p[0]), tilts = pts.map((p) => p[1]);
  return { pan: [Math.min(...pans) - MARGIN_DEG, Math.max(...pans) + MARGIN_DEG],
           tilt: [Math.min(...tilts) - MARGIN_DEG, Math.max(...tilts) + MARGIN_DEG] };
}

// Degrees to canvas pixels, equal scale on both axes, +pan to the left and tilt up: the limb's
// directions as seen from behind it (it rests along +x; +pan turns it toward +y, to the left),
// so left on the plane, the arrow key Left and the terminal's Left all turn the limb one way.
function projector() {
  const b = bounds();
  const pad = 30;
  const w = canvas.width - 2 * pad, h = canvas.height - 2 * pad;
  const spanPan = b.pan[1] - b.pan[0], spanTilt = b.tilt[1] - b.tilt[0];
  const scale = Math.min(w / spanPan, h / spanTilt);
  const x0 = pad + (w - scale * spanPan) / 2, y0 = pad + (h - scale * spanTilt) / 2;
  return {
    bounds: b,
    scale: scale,
    x: (pan) => x0 + (b.pan[1] - pan) * scale,
    y: (tilt) => y0 + (b.tilt[1] - tilt) * scale,
    pan: (x) => b.pan[1] - (x - x0) / scale,
    tilt: (y) => b.tilt[1] - (y - y0) / scale,
  };
}

function drawGrid(P) {
  const b = P.bounds;
  ctx.font = "bold 12px sans-serif";
  ctx.fillStyle = "#555";
  ctx.fillText("seen from behind the limb: \u2190 +pan (left), \u2191 +tilt (up)", 8, 14);
  const step = (b.pan[1] - b.pan[0]) > 120 ? 30 : 10;
  ctx.lineWidth = 1;
  ctx.font = "11px sans-serif";
  ctx.fillStyle = "#777";
  for (let pan = Math.ceil(b.pan[0] / step) * step; pan <= b.pan[1]; pan += step) {
    ctx.strokeStyle = pan === 0 ? COLORS.axis : COLORS.grid;
    ctx.beginPath(); ctx.moveTo(P.x(pan), P.y(b.tilt[0])); ctx.lineTo(P.x(pan), P.y(b.tilt[1])); ctx.stroke();
    ctx.fillText(String(pan), P.x(pan) + 2, P.y(b.tilt[0]) + 12);
  }
  for (let tilt = Math.ceil(b.tilt[0] / step) * step; tilt <= b.tilt[1]; tilt += step) {
    ctx.strokeStyle = tilt === 0 ? COLORS.axis : COLORS.grid;
    ctx.beginPath(); ctx.moveTo(P.x(b.pan[0]), P.y(tilt)); ctx.lineTo(P.x(b.pan[1]), P.y(tilt)); ctx.stroke();
    ctx.fillText(String(tilt), P.x(b.pan[1]) - 24, P.y(tilt) + 4);  // on the left: the largest pan
  }
}

function drawRegion(P, loops) {
  if (loops.length === 0) return;
  ctx.beginPath();
  for (const loop of loops) {
    loop.points.forEach((p, i) => (i ? ctx.lineTo(P.x(p[0]), P.y(p[1])) : ctx.moveTo(P.x(p[0]), P.y(p[1]))));
    ctx.closePath();
  }
  ctx.fillStyle = COLORS.region;
  ctx.fill("evenodd");
  ctx.lineWidth = 3;
  for (const loop of loops) {
    const n = loop.points.length;
    for (let i = 0; i < n; i++) {
      const a = loop.points[i], b = loop.points[(i + 1) % n];
      ctx.strokeStyle = loop.traced[i] ? COLORS.traced : COLORS.untraced;
      ctx.setLineDash(loop.traced[i] ? [] : [6, 4]);
      ctx.beginPath(); ctx.moveTo(P.x(a[0]), P.y(a[1])); ctx.lineTo(P.x(b[0]), P.y(b[1])); ctx.stroke();
    }
  }
  ctx.setLineDash([]);
}

function drawLimits(P, limits) {
  if (!limits) return;
  ctx.strokeStyle = COLORS.limits;
  ctx.lineWidth = 2;
  ctx.setLineDash([8, 4]);
  ctx.strokeRect(P.x(limits.pan[1]), P.y(limits.tilt[1]),
                 (limits.pan[1] - limits.pan[0]) * P.scale, (limits.tilt[1] - limits.tilt[0]) * P.scale);
  ctx.setLineDash([]);
}

function drawMarker(P, pose, kind) {
  if (!pose) return;
  const x = P.x(pose[0]), y = P.y(pose[1]);
  ctx.lineWidth = 2;
  ctx.strokeStyle = ctx.fillStyle = COLORS[kind];
  ctx.beginPath();
  if (kind === "pose") { ctx.arc(x, y, 7, 0, 2 * Math.PI); ctx.fill(); }
  else if (kind === "written") { ctx.arc(x, y, 11, 0, 2 * Math.PI); ctx.stroke(); }
  else { ctx.moveTo(x - 9, y - 9); ctx.lineTo(x + 9, y + 9); ctx.moveTo(x + 9, y - 9); ctx.lineTo(x - 9, y + 9); ctx.stroke(); }
}

// The written pose's last seconds, fading into the past.
function drawTrail(P) {
  const t = state.trail;
  if (t.length < 2) return;
  ctx.strokeStyle = COLORS.trail;
  ctx.lineWidth = 3;
  ctx.beginPath();
  t.forEach((p, i) => (i ? ctx.lineTo(P.x(p[0]), P.y(p[1])) : ctx.moveTo(P.x(p[0]), P.y(p[1]))));
  ctx.stroke();
}

// A short thick wall beside the written pose on each blocked side: the edge that holds it.
function drawBlocked(P, pose, blocked) {
  if (!pose || !blocked) return;
  const x = P.x(pose[0]), y = P.y(pose[1]), r = 16, half = 12;
  ctx.strokeStyle = COLORS.blocked;
  ctx.lineWidth = 5;
  for (const d of blocked) {
    const sx = d === "+pan" ? -1 : d === "-pan" ? 1 : 0, sy = d === "+tilt" ? -1 : d === "-tilt" ? 1 : 0;
    ctx.beginPath();
    ctx.moveTo(x + sx * r - sy * half, y + sy * r - sx * half);
    ctx.lineTo(x + sx * r + sy * half, y + sy * r + sx * half);
    ctx.stroke();
  }
}

// The scene (grid, region, samples, limits) changes about twice a second: it is drawn once
// into an offscreen layer, and each live frame only copies that layer and draws the markers.
const sceneLayer = document.createElement("canvas");
sceneLayer.width = canvas.width;
sceneLayer.height = canvas.height;
let sceneDirty = true;
let layerBounds = "";

function drawScene(P) {
  const layer = sceneLayer.getContext("2d");
  const screen = ctx;
  ctx = layer;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  drawGrid(P);
  const s = state.scene;
  if (s) {
    drawRegion(P, s.loops);
    ctx.fillStyle = COLORS.sample;
    for (const p of s.samples) ctx.fillRect(P.x(p[0]) - 1, P.y(p[1]) - 1, 2, 2);
    drawLimits(P, s.limits);
  }
  ctx = screen;
}

function draw() {
  drawPending = false;
  const P = projector();
  // without limits the window follows the data: a new window redraws the scene layer too
  const key = JSON.stringify(P.bounds);
  if (sceneDirty || key !== layerBounds) {
    drawScene(P);
    sceneDirty = false;
    layerBounds = key;
  }
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.drawImage(sceneLayer, 0, 0);
  const live = state.live;
  if (live) {
    if (live.teleop) {
      drawTrail(P);
      drawMarker(P, live.teleop.commanded, "commanded");
      drawMarker(P, live.teleop.written, "written");
      drawBlocked(P, live.teleop.written, gateWords(live.teleop).blocked);
    }
    drawMarker(P, live.pose, "pose");
    for (const layer of layers) if (layer.draw) layer.draw(ctx, P, live);
  }
}

function scheduleDraw() {
  if (!drawPending) { drawPending = true; requestAnimationFrame(draw); }
}

function showScene(s) {
  byId("region-note").textContent = s.region_note || "-";
  byId("loop-count").textContent = String(s.loops.length);
  let total = 0, traced = 0;
  s.loops.forEach((l) => { total += l.traced.length; traced += l.traced.reduce((a, b) => a + b, 0); });
  byId("traced-share").textContent = total ? `${(100 * traced / total).toFixed(0)} % of ${total} stretches` : "-";
  byId("limits").textContent = s.limits
    ? `pan ${s.limits.pan[0]}..${s.limits.pan[1]}, tilt ${s.limits.tilt[0]}..${s.limits.tilt[1]}` : "-";
  const guide = byId("guide");
  guide.replaceChildren();
  if (s.guide.length === 0) {
    guide.insertRow().insertCell().textContent = "no guide figures yet";
  }
  for (const f of s.guide) {
    const row = guide.insertRow();
    const th = document.createElement("th");
    th.textContent = f.label;
    row.appendChild(th);
    // counts (whole, no unit) as they are; measures to one decimal
    const value = Number.isInteger(f.value) && !f.unit ? String(f.value) : f.value.toFixed(1);
    row.insertCell().textContent = `${value} ${f.unit}`.trim();
  }
  byId("guide-text").textContent = s.guide_text;
}

// The gate's words as this page tells them. The server names blocked every way the point lies
// beyond the written pose; while an arrow key of this page pushes (control.js sets
// window.limbview.pushing), only the way it pushes may be called blocked, as in the terminal.
function gateWords(t) {
  const pushing = window.limbview.pushing;
  const said = { words: t.words || t.outcome, blocked: t.blocked || [] };
  const parts = /^(at [^:]+): .+ (?:is|are) blocked, (.+)$/.exec(said.words);
  if (!pushing || !parts || !t.commanded || !t.written) return said;
  const blocked = pushing.filter((d) => {
    const i = d.endsWith("pan") ? 0 : 1, sign = d[0] === "+" ? 1 : -1;
    return sign * (t.commanded[i] - t.written[i]) > BLOCKED_MIN_DEG;
  });
  if (blocked.length === 0) return { words: `${parts[1]}: ${parts[2]}`, blocked: [] };
  const ways = blocked.map((d) => DIRECTION_NAMES[d]).join(" and ");
  return { words: `${parts[1]}: ${ways} ${blocked.length === 1 ? "is" : "are"} blocked, ${parts[2]}`, blocked: blocked };
}

function showLive(l) {
  // rows about teaching mean nothing in teleop (no samples, the model's edge)
  for (const id of ["sample-count", "traced-share"]) byId(id).parentElement.hidden = Boolean(l.teleop);
  byId("mode").textContent = l.mode;
  byId("note").textContent = l.note;
  byId("sample-count").textContent = String(l.sample_count);
  byId("pose").textContent = fmtPose(l.pose);
  const fault = byId("fault");
  fault.textContent = l.fault;
  fault.hidden = !l.fault;
  const t = l.teleop;
  byId("teleop").hidden = !t;
  // teleop tells its own story: its legend, no guide (nothing is being taught)
  byId("legend-record").hidden = Boolean(t);
  byId("legend-teleop").hidden = !t;
  byId("guide-panel").hidden = Boolean(t);
  if (t) {
    const last = state.trail[state.trail.length - 1];
    if (t.written && (!last || last[0] !== t.written[0] || last[1] !== t.written[1])) {
      state.trail.push(t.written);
      if (state.trail.length > TRAIL_LENGTH) state.trail.shift();
    }
    const said = gateWords(t);
    byId("words").textContent = said.words;
    byId("holds").textContent = said.blocked.length
      ? `the ${said.blocked.map((d) => EDGE_WORDS[d]).join(" and ")} edge` : "nothing: free to move";
    byId("commanded").textContent = fmtPose(t.commanded);
    byId("written").textContent = fmtPose(t.written);
    byId("outcome").textContent = t.outcome;
    byId("rate").textContent = `${t.rate_hz.toFixed(1)} Hz`;
    byId("cycles").textContent = String(t.cycles);
  }
  for (const layer of layers) if (layer.show) layer.show(l);
}

// What the connection asks for: the page's first one takes control as a person opened (or
// reloaded) it; one made after a drop comes back watching (a person's click takes it again).
function query() {
  if (!KEY) return WATCH ? `?watch=${encodeURIComponent(WATCH)}` : "";
  const want = state.opened > 0 ? "watch" : NAVIGATION === "reload" ? "reload" : "take";
  return `?key=${encodeURIComponent(KEY)}&tab=${TAB.id}&name=${encodeURIComponent(TAB.name)}&want=${want}`;
}

function connect() {
  const socket = new WebSocket(`ws://${location.host}/ws${query()}`);
  state.socket = socket;
  socket.onopen = () => { state.opened++; byId("connection").textContent = "live"; byId("connection").className = "up"; };
  socket.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.kind === "scene") { state.scene = message; state.sceneFrames++; sceneDirty = true; showScene(message); }
    else if (message.kind === "live") { state.live = message; state.liveFrames++; showLive(message); }
    else if (message.kind === "control" && window.limbview.onControl) window.limbview.onControl(message);
    if (window.limbview.onMessage) window.limbview.onMessage(message);  // twist.js
    byId("live-frames").textContent = String(state.liveFrames);
    byId("scene-frames").textContent = String(state.sceneFrames);
    scheduleDraw();
  };
  socket.onclose = () => {
    if (window.limbview.onDrop) window.limbview.onDrop();  // control.js: control is gone
    byId("connection").textContent = "disconnected, retrying";
    byId("connection").className = "down";
    setTimeout(connect, RECONNECT_MS);
  };
}

// For tests and the curious: where a pose lands on the canvas, and what was last received.
window.limbview = {
  state: state,
  tab: TAB,
  keyed: Boolean(KEY),
  toCanvas: (pan, tilt) => { const P = projector(); return [P.x(pan), P.y(tilt)]; },
  fromCanvas: (x, y) => { const P = projector(); return [P.pan(x), P.tilt(y)]; },
  send: (text) => { if (state.socket && state.socket.readyState === WebSocket.OPEN) state.socket.send(text); },
  redraw: () => scheduleDraw(),
  addLayer: (layer) => { layers.push(layer); scheduleDraw(); },
  pixel: (pan, tilt) => {
    const P = projector();
    return Array.from(ctx.getImageData(Math.round(P.x(pan)), Math.round(P.y(tilt)), 1, 1).data);
  },
};

if (KEY) byId("tab-name").textContent = `this is ${TAB.name}`;
draw();
connect();
