// "The robot is here" on a map canvas, shared by the Commander and the LDH study: press where
// the robot is and drag towards where it faces (mouse or touch), or use the keyboard: arrows move
// a cursor (Shift for small steps), [ and ] (or Q and E) turn it, Enter marks, Escape removes it.
import {TableMap} from "./maputil.js";
import {facingWords, m} from "./mapwords.js";
import {t} from "./i18n.js";

const STEP_M = 0.05, TURN = Math.PI / 4;

function describe(c) {
  return t("Cursor {x} m from the left, {y} m from the bottom, {facing}. Press Enter to mark the robot here.",
    {x: m(c.x), y: m(c.y), facing: facingWords(c.heading)});
}

// start(): the mark the keyboard cursor starts from (or null: the map's centre);
// mark(x, y, heading): the person marked the robot (heading null when not given);
// redraw(): draw the map again (read the cursor with tool.cursor()); note(text): say it aloud.
export function markTool(canvas, {start, mark, redraw, note}) {
  let press = null, cursor = null;
  const put = (x, y, heading) => { const at = TableMap.clamp(x, y); mark(at.x, at.y, heading); };

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
    put(at.x, at.y, Math.hypot(dx, dy) > 8 ? Math.atan2(-dy, dx) : null);  // canvas y points down
  });
  canvas.addEventListener("pointercancel", () => { press = null; });

  canvas.addEventListener("keydown", (ev) => {
    const moves = {ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1]};
    const turns = {"[": 1, q: 1, Q: 1, "]": -1, e: -1, E: -1};
    if (!(ev.key in moves) && !(ev.key in turns) && ev.key !== "Enter" && ev.key !== "Escape") return;
    ev.preventDefault();
    if (ev.key === "Escape") { cursor = null; note(t("Cursor removed.")); redraw(); return; }
    if (!cursor) {
      const from = start() || {x: TableMap.W_M / 2, y: TableMap.H_M / 2};
      cursor = {x: from.x, y: from.y, heading: from.heading ?? 0};
    }
    if (ev.key === "Enter") {
      const c = cursor;
      cursor = null;
      put(c.x, c.y, c.heading);
      note(t("Marked: the robot is here."));
      redraw(); return;
    }
    if (ev.key in moves) {
      const [dx, dy] = moves[ev.key], step = ev.shiftKey ? STEP_M / 5 : STEP_M;
      Object.assign(cursor, TableMap.clamp(cursor.x + dx * step, cursor.y + dy * step));
    } else {
      const h = cursor.heading + turns[ev.key] * TURN;
      cursor.heading = Math.atan2(Math.sin(h), Math.cos(h));
    }
    note(describe(cursor));
    redraw();
  });
  canvas.addEventListener("blur", () => { if (cursor) { cursor = null; redraw(); } });
  return {cursor: () => cursor};
}
