// limbctl live view, steering: with the session's key in the address, the page may steer.
// Drag or click on the pan/tilt plane to set the commanded point; the arrow keys move it.
// The point is sent as the same JSON line every source sends ({"pan": deg, "tilt": deg}), and
// sent again every SEND_MS while this page steers: a page that freezes or goes away stops
// sending, and the loop holds the last safe pose after its silence. The gate decides the rest.
"use strict";

// Resend period (ms): 20 Hz, ten sends within the loop's 0.5 s silence.
const SEND_MS = 50;
// Degrees one arrow key press moves the commanded point (the browser repeats a held key).
const ARROW_STEP_DEG = 1;
// Arrow keys on the plane as drawn: right is +pan, up is +tilt.
const ARROWS = { ArrowRight: [1, 0], ArrowLeft: [-1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };

const steer = { allowed: false, aim: null, dragging: false };
const plane = document.getElementById("plane");

function setAim(pan, tilt) {
  steer.aim = [Math.round(pan * 100) / 100, Math.round(tilt * 100) / 100];
  sendAim();
}

function sendAim() {
  if (steer.allowed && steer.aim) window.limbview.send(JSON.stringify({ pan: steer.aim[0], tilt: steer.aim[1] }));
}

function planePoint(event) {
  // the canvas may be drawn at another size than its pixels: scale the offset into them
  const x = event.offsetX * (plane.width / plane.clientWidth);
  const y = event.offsetY * (plane.height / plane.clientHeight);
  return window.limbview.fromCanvas(x, y);
}

plane.addEventListener("pointerdown", (event) => {
  if (!steer.allowed) return;
  steer.dragging = true;
  plane.setPointerCapture(event.pointerId);
  setAim(...planePoint(event));
});
plane.addEventListener("pointermove", (event) => { if (steer.allowed && steer.dragging) setAim(...planePoint(event)); });
plane.addEventListener("pointerup", () => { steer.dragging = false; });
plane.addEventListener("pointercancel", () => { steer.dragging = false; });

document.addEventListener("keydown", (event) => {
  const move = ARROWS[event.key];
  if (!steer.allowed || !move) return;
  event.preventDefault();
  // the first press starts from the written pose (where the limb is), not from nowhere
  const live = window.limbview.state.live;
  const from = steer.aim || (live && live.teleop && live.teleop.written) || (live && live.pose);
  if (!from) return;
  setAim(from[0] + move[0] * ARROW_STEP_DEG, from[1] + move[1] * ARROW_STEP_DEG);
});

window.limbview.onControl = (message) => {
  steer.allowed = message.steer;
  plane.classList.toggle("steering", message.steer);
  document.getElementById("control").textContent = message.told;
  document.getElementById("steer-hint").textContent = message.steer
    ? "drag or click to steer; arrow keys move the point" : "";
};
window.limbview.steer = steer;

setInterval(sendAim, SEND_MS);
