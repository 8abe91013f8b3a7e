// Commander: the map with the three landmarks (the next one ringed), the "robot is here" tool
// (mouse, touch or keyboard), the next target's image and the Driver's claims.
import {$, on, send, status, token} from "./seat.js";
import {showImage, TableMap} from "./maputil.js";
import {RUNNING} from "./trial.js";

const root = $("seat");
const landmarks = JSON.parse(root.dataset.landmarks);  // name -> [x, y] metres
const targets = JSON.parse(root.dataset.targets);
const canvas = $("map"), ctx = canvas.getContext("2d");
const map = new Image();
const STORE = `robotslang:estimate:${token}`;
const STEP_M = 0.05, TURN = Math.PI / 4;
let estimate = load(), press = null, cursor = null;

map.onload = draw;
map.onerror = () => { $("map-hint").textContent = "The map could not be loaded. Reload the page."; };
map.src = `/play/${encodeURIComponent(token)}/map.png`;

function load() {
  try { return JSON.parse(localStorage.getItem(STORE)); } catch (e) { return null; }
}
function keep(e) {
  estimate = e;
  try { localStorage.setItem(STORE, JSON.stringify(e)); } catch (err) { /* private mode: the page still works */ }
}

function nextTarget() {
  return RUNNING.has(status.phase) ? targets[status.target_index] : null;
}

function draw() {
  if (map.complete && map.naturalWidth) ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
  else { ctx.fillStyle = "#222"; ctx.fillRect(0, 0, canvas.width, canvas.height); }
  const next = nextTarget();
  if (next && landmarks[next]) TableMap.drawTargetMark(ctx, canvas, ...landmarks[next]);
  if (estimate) TableMap.drawRobot(ctx, canvas, estimate.x, estimate.y, estimate.heading, "#ff8c00");
  if (cursor) TableMap.drawRobot(ctx, canvas, cursor.x, cursor.y, cursor.heading, "#ffffff", {dashed: true});
  canvas.dataset.estimate = estimate ? `${estimate.x.toFixed(3)},${estimate.y.toFixed(3)}` : "";
  document.querySelectorAll("#legend li[data-landmark]").forEach((li) => {
    const isNext = li.dataset.landmark === next;
    li.classList.toggle("next", isNext);
    li.querySelector(".next-note").textContent = isNext ? " (next target)" : "";
  });
}

function localize(x, y, heading) {
  const at = TableMap.clamp(x, y);
  if (send("localize", {x: at.x, y: at.y, heading})) { keep({x: at.x, y: at.y, heading}); draw(); }
}

// -- mouse and touch: press where the robot is, drag towards where it faces ------------------
function point(ev) {
  const r = canvas.getBoundingClientRect();
  return {cx: (ev.clientX - r.left) * canvas.width / r.width, cy: (ev.clientY - r.top) * canvas.height / r.height};
}
canvas.addEventListener("pointerdown", (ev) => {
  press = point(ev);
  canvas.setPointerCapture(ev.pointerId);
});
canvas.addEventListener("pointerup", (ev) => {
  if (!press) return;
  const up = point(ev), at = TableMap.toWorld(canvas, press.cx, press.cy);
  const dx = up.cx - press.cx, dy = up.cy - press.cy;
  press = null;
  localize(at.x, at.y, Math.hypot(dx, dy) > 8 ? Math.atan2(-dy, dx) : null);  // canvas y points down
});
canvas.addEventListener("pointercancel", () => { press = null; });

// -- keyboard: arrows move a cursor, [ and ] (or Q and E) turn it, Enter marks the robot -------
const COMPASS = ["east", "north-east", "north", "north-west", "west", "south-west", "south", "south-east"];
function describe(c) {
  const k = ((Math.round(c.heading / TURN) % 8) + 8) % 8;
  return `Cursor ${c.x.toFixed(2)} m from the left, ${c.y.toFixed(2)} m from the bottom, facing ${COMPASS[k]}. ` +
    "Press Enter to mark the robot here.";
}
canvas.addEventListener("keydown", (ev) => {
  const moves = {ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1]};
  const turns = {"[": 1, q: 1, Q: 1, "]": -1, e: -1, E: -1};
  if (!(ev.key in moves) && !(ev.key in turns) && ev.key !== "Enter" && ev.key !== "Escape") return;
  ev.preventDefault();
  if (ev.key === "Escape") { cursor = null; $("cursor-note").textContent = "Cursor removed."; draw(); return; }
  if (!cursor) {
    const from = estimate || {x: TableMap.W_M / 2, y: TableMap.H_M / 2};
    cursor = {x: from.x, y: from.y, heading: from.heading ?? 0};
  }
  if (ev.key === "Enter") {
    localize(cursor.x, cursor.y, cursor.heading);
    $("cursor-note").textContent = "Marked: the robot is here.";
    cursor = null; draw(); return;
  }
  if (ev.key in moves) {
    const [dx, dy] = moves[ev.key], step = ev.shiftKey ? STEP_M / 5 : STEP_M;
    Object.assign(cursor, TableMap.clamp(cursor.x + dx * step, cursor.y + dy * step));
  } else {
    cursor.heading = Math.atan2(Math.sin(cursor.heading + turns[ev.key] * TURN), Math.cos(cursor.heading + turns[ev.key] * TURN));
  }
  $("cursor-note").textContent = describe(cursor);
  draw();
});
canvas.addEventListener("blur", () => { if (cursor) { cursor = null; draw(); } });

// -- the next target and claims -----------------------------------------------------------------
function showTarget() {
  const next = nextTarget(), index = status.target_index;
  $("target-name").textContent = status.phase === "finished" ? "all three found!" : (next || "—");
  const img = $("target-image"), src = next ? `/play/${encodeURIComponent(token)}/target/${index}.jpg` : "";
  if (img.dataset.src !== src) {
    img.dataset.src = src;
    img.alt = next ? `the ${next}, as the robot's camera would see it` : "";
    showImage(img, src);
  }
  $("map-hint").textContent = status.phase === "localizing"
    ? "Mark where you think the robot is: click (drag to give its heading), tap, or use the keyboard."
    : RUNNING.has(status.phase) ? "You can mark the robot again at any time." : "";
  draw();
}
function showClaim(claim) {
  const box = $("claim");
  if (!claim || !claim.jpeg) { box.hidden = true; return; }
  showImage($("claim-image"), `data:image/jpeg;base64,${claim.jpeg}`);
  box.hidden = false;
  $("confirm").focus();
}

on("welcome", (msg) => {
  if (msg.localization) keep(msg.localization);  // the server's copy wins over this browser's
  showClaim(msg.claim || null);
});
on("status", showTarget);
on("localization", (msg) => { keep(msg.payload); draw(); });
on("target_claimed", (msg) => showClaim(msg.claim));
on("target_confirmed", () => showClaim(null));
on("target_rejected", () => showClaim(null));
on("phase", (msg) => { if (msg.payload.phase !== "navigating" && msg.payload.phase !== "localizing") showClaim(null); });
$("confirm").addEventListener("click", () => send("confirm"));
$("reject").addEventListener("click", () => send("reject"));
