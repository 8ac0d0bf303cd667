// limbctl live view, steering: with the session's key in the address, the page may steer.
// Drag or click on the pan/tilt plane to set the commanded point; the arrow keys move it.
// The point is sent as the same JSON line every source sends ({"pan": deg, "tilt": deg}), and
// sent again every SEND_MS while this page steers: a page that freezes or goes away stops
// sending, and the loop holds the last safe pose after its silence. The gate decides the rest.
//
// Nothing moves without a fresh action: the page sends no point until a person drags, clicks or
// presses a key after this tab got control; a tab that lost control (its connection dropped)
// comes back watching and steers again only on a click on "take control"; a tab that was
// paused longer than the loop's silence drops its point; an arrow key steps from the pose the
// gate wrote when the gate stopped the point short (an edge, a hard limit), so the point never
// runs on past the limb and the first opposite key moves it a full step at once.
"use strict";

// Resend period (ms): 20 Hz, ten sends within the loop's 0.5 s silence.
const SEND_MS = 50;
// Longest gap (ms) between two resends before the point is dropped: the loop's 0.5 s silence.
// A longer gap (a frozen or hidden tab) has let the loop hold; sending the old point again
// would move the limb with nobody acting.
const STALE_MS = 500;
// Degrees one arrow key press moves the commanded point (the browser repeats a held key).
const ARROW_STEP_DEG = 1;
// Arrow keys as the limb moves, seen from behind it (the plane is drawn that way): left is
// +pan, up is +tilt; the terminal's keys mean the same.
const ARROWS = { ArrowLeft: [1, 0], ArrowRight: [-1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };
// Gate outcomes that stopped the point short of where it was sent.
const STOPPED = ["corrected", "clamped"];

const steer = {
  allowed: false, aim: null, dragging: false, message: null,
  lost: "", paused: "", lettingGo: false, ticks: 0, lastTick: performance.now(),
};
const plane = document.getElementById("plane");

function clock() { return new Date().toTimeString().slice(0, 8); }

function setAim(pan, tilt) {
  steer.aim = [Math.round(pan * 100) / 100, Math.round(tilt * 100) / 100];
  steer.paused = "";
  showControl();
  sendAim();
}

function sendAim() {
  if (steer.allowed && steer.aim) window.limbview.send(JSON.stringify({ pan: steer.aim[0], tilt: steer.aim[1] }));
}

// Every SEND_MS: resend the point, unless this tab was paused past the loop's silence.
function tick() {
  const now = performance.now();
  const gap = now - steer.lastTick;
  steer.lastTick = now;
  steer.ticks++;
  if (gap > STALE_MS && steer.aim) {
    steer.aim = null;
    steer.paused = `this tab was paused ${(gap / 1000).toFixed(1)} s (${clock()}): its point was ` +
      "dropped; drag, click or press a key to steer again";
    showControl();
  }
  sendAim();
}

function planePoint(event) {
  // the canvas may be drawn at another size than its pixels: scale the offset into them
  const x = event.offsetX * (plane.width / plane.clientWidth);
  const y = event.offsetY * (plane.height / plane.clientHeight);
  return window.limbview.fromCanvas(x, y);
}

plane.addEventListener("pointerdown", (event) => {
  if (!steer.allowed) return;
  window.limbview.pushing = null;  // a point set by hand: the whole gap is what is asked
  steer.dragging = true;
  plane.setPointerCapture(event.pointerId);
  setAim(...planePoint(event));
});
plane.addEventListener("pointermove", (event) => { if (steer.allowed && steer.dragging) setAim(...planePoint(event)); });
plane.addEventListener("pointerup", () => { steer.dragging = false; });
plane.addEventListener("pointercancel", () => { steer.dragging = false; });

// Where an arrow key steps from: the point, or the written pose when there is no point yet or
// the gate stopped the point short of it (the point never runs on past the limb).
function keyBase() {
  const live = window.limbview.state.live;
  const t = live && live.teleop;
  const written = (t && t.written) || (live && live.pose);
  if (!steer.aim) return written;
  const stopped = t && t.written && STOPPED.includes(t.outcome);
  return stopped ? t.written : steer.aim;
}

document.addEventListener("keydown", (event) => {
  const move = ARROWS[event.key];
  if (!steer.allowed || !move) return;
  event.preventDefault();
  const from = keyBase();
  if (!from) return;
  // the way this key pushes, the only one view.js may call blocked
  window.limbview.pushing = [move[0] > 0 ? "+pan" : move[0] < 0 ? "-pan" : move[1] > 0 ? "+tilt" : "-tilt"];
  setAim(from[0] + move[0] * ARROW_STEP_DEG, from[1] + move[1] * ARROW_STEP_DEG);
});

function showControl() {
  const message = steer.message;
  if (!message) return;
  let told = message.told;
  if (!message.steer && steer.lost) told = `${steer.lost}; ${told}`;
  if (message.steer && steer.paused) told = `${told}; ${steer.paused}`;
  document.getElementById("control").textContent = told;
  const keyed = window.limbview.keyed && message.keyed;
  const refused = told.includes("takes no commands from the page");
  document.getElementById("take").hidden = !keyed || message.steer || refused;
  document.getElementById("let-go").hidden = !message.steer;
  document.getElementById("steer-hint").textContent = message.steer
    ? "drag or click to steer; arrow keys move the point (left/right as seen from behind the limb)" : "";
  if (keyed) document.title = `limbctl: ${window.limbview.tab.name} ${message.steer ? "steers" : "watches"}`;
}

window.limbview.onControl = (message) => {
  if (message.steer && !steer.allowed) {  // control (re)gained: a fresh action starts anew
    steer.aim = null;
    steer.lost = steer.paused = "";
  } else if (!message.steer && steer.allowed) {
    steer.aim = null;
    steer.lost = steer.lettingGo ? `you let go at ${clock()}` : `this tab lost control at ${clock()}`;
  }
  steer.lettingGo = false;
  if (!message.steer) window.limbview.pushing = null;
  steer.allowed = message.steer;
  steer.message = message;
  plane.classList.toggle("steering", message.steer);
  showControl();
};

// The connection dropped: control is gone with it, and a reconnection comes back watching.
window.limbview.onDrop = () => {
  if (steer.allowed) {
    steer.lost = `this tab lost control when its connection dropped at ${clock()} and came back watching`;
  }
  steer.allowed = false;
  steer.aim = null;
  plane.classList.remove("steering");
  if (steer.message) steer.message = { ...steer.message, steer: false, told: "reconnecting" };
  showControl();
};

document.getElementById("take").addEventListener("click", () => {
  window.limbview.send(JSON.stringify({ control: "take" }));
});
document.getElementById("let-go").addEventListener("click", () => {
  steer.lettingGo = true;
  window.limbview.send(JSON.stringify({ control: "release" }));
});
window.limbview.steer = steer;

setInterval(tick, SEND_MS);
