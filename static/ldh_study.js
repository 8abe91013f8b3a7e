// An LDH study participant: the Commander's map of this instance, the mark tool shared with the
// Commander, and a submit that moves on to the next instance once the server has recorded it.
import {csrfHeaders, TableMap} from "./maputil.js";
import {markTool} from "./marktool.js";
import {t} from "./i18n.js";

const $ = (id) => document.getElementById(id);
const root = $("ldh"), token = root.dataset.token, position = Number(root.dataset.position);
const canvas = $("map"), ctx = canvas.getContext("2d");
const map = new Image();
let mark = null;

function draw() {
  if (map.complete && map.naturalWidth) ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
  else { ctx.fillStyle = "#222"; ctx.fillRect(0, 0, canvas.width, canvas.height); }
  if (mark) TableMap.drawRobot(ctx, canvas, mark.x, mark.y, mark.heading, "#ff8c00");
  const cursor = tool.cursor();
  if (cursor) TableMap.drawRobot(ctx, canvas, cursor.x, cursor.y, cursor.heading, "#ffffff", {dashed: true});
  canvas.dataset.estimate = mark ? `${mark.x.toFixed(3)},${mark.y.toFixed(3)}` : "";
}

const tool = markTool(canvas, {
  start: () => mark,
  mark: (x, y, heading) => { mark = {x, y, heading}; $("submit").disabled = false; draw(); },
  redraw: draw,
  note: (text) => { $("cursor-note").textContent = text; },
});

$("submit").addEventListener("click", async () => {
  if (!mark) return;
  $("submit").disabled = true;
  try {
    const reply = await fetch(`/ldh/${encodeURIComponent(token)}/answers`, {
      method: "POST", headers: {"Content-Type": "application/json", ...csrfHeaders()},
      body: JSON.stringify({position, ...mark}),
    });
    if (reply.ok) { location.reload(); return; }
    const body = await reply.json().catch(() => ({}));
    $("error").textContent = body.detail || t("The answer was not recorded ({status}). Reload the page.", {status: reply.status});
  } catch (err) {
    $("error").textContent = t("The answer was not sent (no connection). Try again.");
  }
  $("submit").disabled = false;
});

map.onload = draw;
map.onerror = () => { $("map-hint").textContent = t("The map could not be loaded. Reload the page."); };
map.src = `/ldh/${encodeURIComponent(token)}/map/${position}.png`;
draw();
