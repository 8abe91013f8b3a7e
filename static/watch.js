// The experimenter's view of one trial: status, clock and moves, the full map with the true pose
// and the Commander's estimate, and the Driver's live camera. Controls follow the trial's state.
import {TableMap} from "./maputil.js";
import {confirmFirst, showControls} from "./controls.js";
import {applyStatus, clockSeconds, emptyStatus, formatClock, OVER, statusText} from "./trial.js";

const root = document.getElementById("watch");
const id = Number(root.dataset.trial);
const $ = (x) => document.getElementById(x);
const canvas = $("truth"), ctx = canvas.getContext("2d");
const map = new Image();
const status = Object.assign(emptyStatus(), {phase: root.dataset.phase, targets_total: Number(root.dataset.targets),
                                             elapsed_s: Number(root.dataset.elapsed), moves: Number(root.dataset.moves)});
let latest = null, announced = "", cameraBusy = false;
map.src = `/experimenter/trials/${id}/map.png`;

function draw() {
  if (map.complete && map.naturalWidth) ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
  if (!latest) return;
  if (latest.belief) drawBelief(latest.belief);
  if (latest.localization) TableMap.drawRobot(ctx, canvas, latest.localization.x, latest.localization.y, latest.localization.heading, "#ff8c00");
  if (latest.pose) {
    TableMap.drawRobot(ctx, canvas, latest.pose[0], latest.pose[1], latest.pose[2], "#1e6bff");
    $("pose-note").textContent = `True pose: x ${latest.pose[0].toFixed(2)} m, y ${latest.pose[1].toFixed(2)} m, ` +
      `heading ${Math.round(latest.pose[2] * 180 / Math.PI)}°`;
  }
}

// The particle filter's belief: weighted points and their mean, in purple (experimenter only).
function drawBelief(b) {
  const wmax = Math.max(...b.points.map((p) => p[2]));
  ctx.fillStyle = "#c020c0";
  for (const [x, y, w] of b.points) {
    const {cx, cy} = TableMap.toCanvas(canvas, x, y);
    ctx.globalAlpha = 0.25 + 0.75 * w / wmax;
    ctx.fillRect(cx - 1.5, cy - 1.5, 3, 3);
  }
  ctx.globalAlpha = 1;
  TableMap.drawRobot(ctx, canvas, b.mean[0], b.mean[1], b.mean[2], "#c020c0");
}

function render() {
  const text = statusText(status, "experimenter");
  if (text !== announced) { $("status").textContent = text; announced = text; }
  $("status").dataset.phase = status.phase;
  $("clock").textContent = formatClock(clockSeconds(status));
  if (status.moves !== null) $("moves").textContent = String(status.moves);
  showControls($("controls"), status.phase, status.paused);
}

// The Driver's latest frame, swapped in only once loaded (no flicker, no broken image).
function refreshCamera() {
  if (cameraBusy) return;
  cameraBusy = true;
  const next = new Image();
  next.onload = () => { $("camera").src = next.src; $("camera").hidden = false; $("camera-wait").hidden = true; cameraBusy = false; };
  next.onerror = () => { cameraBusy = false; };
  next.src = `/experimenter/trials/${id}/camera.jpg?t=${Date.now()}`;
}

async function refresh() {
  let t, phases;
  try {
    const res = await fetch("/experimenter/api/trials", {credentials: "same-origin"});
    if (!res.ok) return;
    const body = await res.json();
    t = body.trials.find((x) => x.trial_id === id);
    phases = body.phases || {};
  } catch (e) { return; }  // the next tick retries
  if (t) { latest = t; applyStatus(status, t); }
  else if (phases[id] && phases[id] !== status.phase) {  // no longer open here: its recorded phase
    status.elapsed_s = clockSeconds(status);  // the clock stops where it was
    status.phase = phases[id];
  }
  render(); draw();
  if (!OVER.has(status.phase) || $("camera").hidden) refreshCamera();
}

confirmFirst(document);
map.onload = draw;
setInterval(refresh, 500);
setInterval(render, 250);
refresh();
