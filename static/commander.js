// Commander: the map with the three landmarks (the next one ringed), the "robot is here" tool
// (mouse, touch or keyboard), the next target's image and the Driver's claims.
import {$, on, send, status, token} from "./seat.js";
import {showImage, TableMap} from "./maputil.js";
import {markTool} from "./marktool.js";
import {landmarkWords, markWords, thing, wallWords} from "./mapwords.js";
import {RUNNING} from "./trial.js";
import {calm, raise} from "./alert.js";
import {t} from "./i18n.js";

const root = $("seat");
const landmarks = JSON.parse(root.dataset.landmarks);  // name -> [x, y] metres
const targets = JSON.parse(root.dataset.targets);
const walls = JSON.parse(root.dataset.walls);
const canvas = $("map"), ctx = canvas.getContext("2d");
const map = new Image();
const STORE = `robotslang:estimate:${token}`;
let estimate = load();

map.onload = draw;
map.onerror = () => { $("map-hint").textContent = t("The map could not be loaded. Reload the page."); };
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
  const cursor = tool.cursor();
  if (cursor) TableMap.drawRobot(ctx, canvas, cursor.x, cursor.y, cursor.heading, "#ffffff", {dashed: true});
  canvas.dataset.estimate = estimate ? `${estimate.x.toFixed(3)},${estimate.y.toFixed(3)}` : "";
  document.querySelectorAll("#legend li[data-landmark]").forEach((li) => {
    const isNext = li.dataset.landmark === next;
    li.classList.toggle("next", isNext);
    li.querySelector(".next-note").textContent = isNext ? t(" (next target)") : "";
  });
  inWords(next);
}

// The map in words: the walls once, the landmarks and the mark as they change (never on a cursor move).
function fill(list, lines) {
  list.replaceChildren(...lines.map((line) => Object.assign(document.createElement("li"), {textContent: line})));
}
fill($("map-text-walls"), walls.map(wallWords));
let said = null;
function inWords(next) {
  const now = JSON.stringify([next, estimate]);
  if (now === said) return;
  said = now;
  fill($("map-text-landmarks"), Object.entries(landmarks).map(([name, xy]) => landmarkWords(name, xy, name === next)));
  $("map-text-mark").textContent = markWords(estimate);
}

function localize(x, y, heading) {
  if (send("localize", {x, y, heading})) { keep({x, y, heading}); draw(); }
}

const tool = markTool(canvas, {start: () => estimate, mark: localize, redraw: draw,
                               note: (text) => { $("cursor-note").textContent = text; }});

// -- the next target and claims -----------------------------------------------------------------
function showTarget() {
  const next = nextTarget(), index = status.target_index;
  $("target-name").textContent = status.phase === "finished" ? t("all three found!") : (next ? thing(next) : "—");
  const img = $("target-image"), src = next ? `/play/${encodeURIComponent(token)}/target/${index}.jpg` : "";
  if (img.dataset.src !== src) {
    img.dataset.src = src;
    img.alt = next ? t("the {thing}, as the robot's camera would see it", {thing: thing(next)}) : "";
    showImage(img, src);
  }
  $("map-hint").textContent = status.phase === "localizing"
    ? t("Mark where you think the robot is: click (drag to give its heading), tap, or use the keyboard.")
    : RUNNING.has(status.phase) ? t("You can mark the robot again at any time.") : "";
  draw();
}
function showClaim(claim) {
  const box = $("claim");
  if (!claim || !claim.jpeg) { box.hidden = true; calm(); return; }
  showImage($("claim-image"), `data:image/jpeg;base64,${claim.jpeg}`);
  if (box.hidden) raise(t("Claim to judge"));  // once per claim, not again on a reconnect's welcome
  box.hidden = false;
  $("confirm").focus();
}

on("welcome", (msg) => {
  if (msg.localization) { keep(msg.localization); draw(); }  // the server's copy wins over this browser's
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
