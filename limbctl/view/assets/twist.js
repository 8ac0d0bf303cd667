// limbctl live view, three-servo limbs: the twist over the swing plane and the twist gauge.
// view.js hands every message to window.limbview.onMessage; a scene may carry "twist" (cells of
// the swing plane, each with a twist range: taught so far, or the learned band) and a live
// message "twist" (the present twist against the range at its place). Two-servo messages carry
// neither, and then nothing here shows. No build step, no CDN.
"use strict";

(function () {
  // Colours of the cells by state; "turned" and "band" cells take the width scale instead.
  const CELL = {
    short: "rgb(245, 170, 80)",    // a stop still untaught there
    few: "rgb(255, 255, 255)",     // too few samples to judge (a dotted grey border)
    free: "rgb(235, 245, 235)",    // any twist allowed
    outline: "rgba(0, 0, 0, 0.25)",
    region: "rgba(20, 110, 20, 0.8)",
    pose: "#1f5fd0",
  };
  // The width scale (deg of twist range): narrow pale yellow, through teal, to wide dark blue.
  const SCALE = [[255, 237, 160], [65, 182, 196], [37, 52, 148]];
  const GAUGE = { band: "rgb(150, 220, 150)", axis: "#777", twist: "#1f5fd0", written: "#000" };
  // Degrees around the hard limits (or the cells) so the cells at the edge stay visible.
  const MARGIN_DEG = 5;
  // The smallest cell (px) labelled with its range, the high limit over the low: "-145" in
  // 10 px type fits 26 px.
  const LABEL_PX = 26;

  const plane = document.getElementById("twist-plane");
  const gauge = document.getElementById("twist-gauge");
  const t = { map: null, limits: null, loops: [], live: null, drawn: 0, pending: false };

  function byId(id) { return document.getElementById(id); }
  function fmt(v) { return v === null || v === undefined ? "-" : `${v.toFixed(1)} deg`; }

  function widthColor(width, widest) {
    const f = widest > 0 ? Math.min(1, Math.max(0, width / widest)) : 0;
    const lo = f < 0.5 ? SCALE[0] : SCALE[1], hi = f < 0.5 ? SCALE[1] : SCALE[2];
    const g = f < 0.5 ? 2 * f : 2 * f - 1;
    const c = lo.map((a, k) => Math.round(a + g * (hi[k] - a)));
    return `rgb(${c[0]}, ${c[1]}, ${c[2]})`;
  }

  function fillOf(cell, widest) {
    const state = cell[4];
    if (state === "turned" || state === "band") return widthColor(cell[3] - cell[2], widest);
    return CELL[state];
  }

  function widestOf(map) {
    let w = 0;
    for (const c of map.cells) if (c[4] === "turned" || c[4] === "band") w = Math.max(w, c[3] - c[2]);
    return w;
  }

  // The plotted window (deg): the hard limits when known, else the cells'.
  function projector() {
    const m = t.map, size = m.cell;
    let pan, tilt;
    if (t.limits) {
      pan = [t.limits.pan[0] - MARGIN_DEG, t.limits.pan[1] + MARGIN_DEG];
      tilt = [t.limits.tilt[0] - MARGIN_DEG, t.limits.tilt[1] + MARGIN_DEG];
    } else {
      const is = m.cells.map((c) => c[0]), js = m.cells.map((c) => c[1]);
      pan = [Math.min(...is) * size - MARGIN_DEG, (Math.max(...is) + 1) * size + MARGIN_DEG];
      tilt = [Math.min(...js) * size - MARGIN_DEG, (Math.max(...js) + 1) * size + MARGIN_DEG];
    }
    const pad = 24, legend = 60;
    const w = plane.width - 2 * pad - legend, h = plane.height - 2 * pad;
    const scale = Math.min(w / (pan[1] - pan[0]), h / (tilt[1] - tilt[0]));
    const x0 = pad, y0 = pad + (h - scale * (tilt[1] - tilt[0])) / 2;
    return {
      scale: scale,
      right: x0 + scale * (pan[1] - pan[0]),
      x: (p) => x0 + (pan[1] - p) * scale,  // +pan to the left: seen from behind the limb
      y: (q) => y0 + (tilt[1] - q) * scale,
    };
  }

  function drawPlane() {
    const ctx = plane.getContext("2d");
    ctx.clearRect(0, 0, plane.width, plane.height);
    t.drawn = 0;
    const m = t.map;
    if (!m || m.cells.length === 0) return;
    const P = projector(), size = m.cell, widest = widestOf(m), px = size * P.scale;
    ctx.font = "10px sans-serif";
    ctx.textAlign = "center";
    for (const c of m.cells) {
      const x = P.x((c[0] + 1) * size), y = P.y((c[1] + 1) * size);  // the cell's left edge
      ctx.fillStyle = fillOf(c, widest);
      ctx.fillRect(x, y, px, px);
      ctx.strokeStyle = CELL.outline;
      ctx.lineWidth = 1;
      ctx.strokeRect(x, y, px, px);
      if (c[4] === "short" || c[4] === "few") {  // a stop lacking, too few: a dashed border
        ctx.strokeStyle = c[4] === "short" ? "rgb(200, 90, 0)" : "rgb(150, 150, 150)";
        ctx.setLineDash(c[4] === "short" ? [4, 3] : [2, 2]);
        ctx.strokeRect(x + 1, y + 1, px - 2, px - 2);
        ctx.setLineDash([]);
      }
      if (px >= LABEL_PX && c[4] !== "free") {
        const dark = (c[4] === "turned" || c[4] === "band") && (c[3] - c[2]) > 0.6 * widest;
        ctx.fillStyle = dark ? "#fff" : "#222";
        ctx.fillText(String(Math.round(c[3])), x + px / 2, y + px / 2 - 2);
        ctx.fillText(String(Math.round(c[2])), x + px / 2, y + px / 2 + 10);
      }
      t.drawn++;
    }
    // the swing region's edge, for where the cells lie
    ctx.strokeStyle = CELL.region;
    ctx.lineWidth = 2;
    for (const loop of t.loops) {
      ctx.beginPath();
      loop.points.forEach((p, i) => (i ? ctx.lineTo(P.x(p[0]), P.y(p[1])) : ctx.moveTo(P.x(p[0]), P.y(p[1]))));
      ctx.closePath();
      ctx.stroke();
    }
    // the width scale, beside the plane
    const bx = P.right + 16, top = 30, bottom = plane.height - 40;
    for (let y = top; y <= bottom; y++) {
      ctx.fillStyle = widthColor(widest * (bottom - y) / (bottom - top), widest);
      ctx.fillRect(bx, y, 14, 1);
    }
    ctx.fillStyle = "#333";
    ctx.textAlign = "left";
    ctx.fillText(`${Math.round(widest)}`, bx + 17, top + 8);
    ctx.fillText("0", bx + 17, bottom);
    ctx.fillText("width", bx - 4, top - 14);
    ctx.fillText("(deg)", bx - 4, top - 3);
    const live = t.live;
    if (live && live.pose) {
      ctx.fillStyle = CELL.pose;
      ctx.beginPath();
      ctx.arc(P.x(live.pose[0]), P.y(live.pose[1]), 6, 0, 2 * Math.PI);
      ctx.fill();
    }
  }

  // The gauge: the twist axis -180..180 deg, the range here in green (in two pieces where it
  // crosses +-180), the present twist as a blue needle, the written twist as a black tick.
  const AXIS = { left: 14, right: 14, y: 30 };
  function gaugeX(deg) {
    const w = gauge.width - AXIS.left - AXIS.right;
    return AXIS.left + ((deg + 180) / 360) * w;
  }
  function wrapDeg(v) { return v - 360 * Math.ceil((v - 180) / 360); }

  function drawGauge() {
    const ctx = gauge.getContext("2d");
    ctx.clearRect(0, 0, gauge.width, gauge.height);
    const g = t.live && t.live.twist;
    if (!g) return;
    ctx.strokeStyle = GAUGE.axis;
    ctx.fillStyle = GAUGE.axis;
    ctx.lineWidth = 1;
    ctx.font = "10px sans-serif";
    ctx.textAlign = "center";
    ctx.beginPath(); ctx.moveTo(gaugeX(-180), AXIS.y); ctx.lineTo(gaugeX(180), AXIS.y); ctx.stroke();
    for (const tick of [-180, -90, 0, 90, 180]) {
      ctx.beginPath(); ctx.moveTo(gaugeX(tick), AXIS.y - 4); ctx.lineTo(gaugeX(tick), AXIS.y + 4); ctx.stroke();
      ctx.fillText(String(tick), gaugeX(tick), AXIS.y + 16);
    }
    if (g.low !== null && g.high !== null) {
      ctx.fillStyle = GAUGE.band;
      const lo = wrapDeg(g.low), span = Math.min(360, g.high - g.low);
      const first = Math.min(span, 180 - lo);
      ctx.fillRect(gaugeX(lo), AXIS.y - 8, gaugeX(lo + first) - gaugeX(lo), 16);
      if (span > first) ctx.fillRect(gaugeX(-180), AXIS.y - 8, gaugeX(-180 + span - first) - gaugeX(-180), 16);
    }
    if (g.written !== null) {
      ctx.strokeStyle = GAUGE.written;
      ctx.lineWidth = 2;
      ctx.beginPath(); ctx.moveTo(gaugeX(g.written), AXIS.y - 12); ctx.lineTo(gaugeX(g.written), AXIS.y + 12); ctx.stroke();
    }
    ctx.strokeStyle = ctx.fillStyle = GAUGE.twist;
    ctx.lineWidth = 3;
    const x = gaugeX(g.twist);
    ctx.beginPath(); ctx.moveTo(x, AXIS.y - 16); ctx.lineTo(x, AXIS.y + 8); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(x - 5, AXIS.y - 22); ctx.lineTo(x + 5, AXIS.y - 22); ctx.lineTo(x, AXIS.y - 15); ctx.fill();
  }

  function showGauge(g) {
    byId("twist-now").textContent = fmt(g.twist);
    byId("twist-written").parentElement.hidden = g.written === null;
    byId("twist-written").textContent = fmt(g.written);
    if (g.low === null || g.high === null) {
      byId("twist-range").textContent = g.of || "-";
      byId("twist-margin").textContent = "-";
      return;
    }
    byId("twist-range").textContent = `${g.low.toFixed(1)} .. ${g.high.toFixed(1)} deg (${g.of})`;
    // the twist's turn nearest the range's middle, against both limits
    const v = g.twist + 360 * Math.round(((g.low + g.high) / 2 - g.twist) / 360);
    const room = Math.min(v - g.low, g.high - v);
    // while recording, beyond the range is new twist being taught; in teleop, past the band
    const past = g.of.startsWith("taught") ? "past what was taught here" : "beyond the band";
    byId("twist-margin").textContent = room >= 0
      ? `${room.toFixed(1)} deg inside` : `${(-room).toFixed(1)} deg ${past}`;
  }

  function showMap(m) {
    const counts = {};
    for (const c of m.cells) counts[c[4]] = (counts[c[4]] || 0) + 1;
    const legend = m.of === "taught"
      ? `twist taught so far, by ${m.cell} deg place: colour = its range's width; ` +
        `numbers = the greatest and least twist taught there; orange dashed = a stop still ` +
        `untaught (${counts.short || 0}), white dotted = too few samples ` +
        `(${counts.few || 0}), turned both ways: ${counts.turned || 0}`
      : `the learned twist band, by ${m.cell} deg place: colour = its width (twice the ` +
        `half-width) at the place's centre (numbers, where they fit: its limits there); ` +
        `free twist: ${counts.free || 0} places; the gauge gives the band at the limb`;
    // drawn as the pan/tilt plane above it: seen from behind the limb, +pan to the left
    byId("twist-legend").textContent = `seen from behind the limb (+pan to the left): ${legend}`;
  }

  function draw() { t.pending = false; drawPlane(); drawGauge(); }
  function schedule() { if (!t.pending) { t.pending = true; requestAnimationFrame(draw); } }

  function onMessage(message) {
    if (message.kind === "scene") {
      t.map = message.twist || null;
      t.limits = message.limits;
      t.loops = message.loops;
      byId("twist-figure").hidden = !t.map;
      if (t.map) showMap(t.map);
    } else if (message.kind === "live") {
      t.live = message;
      byId("twist-panel").hidden = !message.twist;
      if (message.twist) showGauge(message.twist);
    } else {
      return;
    }
    if (t.map || (t.live && t.live.twist)) schedule();
  }

  window.limbview.onMessage = onMessage;
  // For tests: cells drawn, a pixel of either canvas, where a twist sits on the gauge.
  window.limbtwist = {
    state: t,
    drawnCells: () => t.drawn,
    gaugeX: gaugeX,
    pixel: (id, x, y) => Array.from(byId(id).getContext("2d").getImageData(Math.round(x), Math.round(y), 1, 1).data),
    cellCentre: (i, j) => {
      const P = projector(), size = t.map.cell;
      return [P.x((i + 0.5) * size), P.y((j + 0.5) * size)];
    },
    // the colours at a cell's four corners, 4 px in (the region's edge may cross one or two)
    cellPixels: (i, j) => {
      const P = projector(), size = t.map.cell, px = size * P.scale, c = plane.getContext("2d");
      const x = P.x((i + 1) * size), y = P.y((j + 1) * size);
      return [[4, 4], [px - 5, 4], [4, px - 5], [px - 5, px - 5]].map(
        ([dx, dy]) => Array.from(c.getImageData(Math.round(x + dx), Math.round(y + dy), 1, 1).data).slice(0, 3));
    },
  };
})();
