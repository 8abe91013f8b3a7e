// The Commander's map in words, for a screen reader: each wall, landmark and the mark, by the
// ninth of the table it is in (north is the top of the map) and in the metres the keyboard
// cursor moves by (x from the left edge, y from the bottom edge).
import {TableMap} from "./maputil.js";

export const COMPASS = ["east", "north-east", "north", "north-west", "west", "south-west", "south", "south-east"];

export function facing(heading) {
  return COMPASS[((Math.round(heading / (Math.PI / 4)) % 8) + 8) % 8];
}

function region(x, y) {
  const col = Math.min(2, Math.floor(3 * x / TableMap.W_M)), row = Math.min(2, Math.floor(3 * y / TableMap.H_M));
  const ns = ["south", "", "north"][Math.max(row, 0)], ew = ["west", "", "east"][Math.max(col, 0)];
  return ns && ew ? `${ns}-${ew}` : ns || ew || "centre";
}

const m = (v) => v.toFixed(2);
const place = (x, y) => `the ${region(x, y)} (x ${m(x)}, y ${m(y)})`;
const at = (x, y) => `in ${place(x, y)}`;

// A wall as the server describes it (app/map_text.py): straight (its ends), bent (the box it spans) or the table's edge.
export function wallWords({colour, shape, from: [x0, y0], to: [x1, y1]}) {
  if (shape === "edge") return `${colour} wall along the table's edge`;
  if (shape === "bent") {
    return `${colour} wall, bent, in the ${region((x0 + x1) / 2, (y0 + y1) / 2)}, ` +
      `within x ${m(x0)} to ${m(x1)} and y ${m(y0)} to ${m(y1)}`;
  }
  return `${colour} wall, ${m(Math.hypot(x1 - x0, y1 - y0))} m long, from ${place(x0, y0)} to ${place(x1, y1)}`;
}

export function landmarkWords(name, [x, y], isNext) {
  return `${name} ${at(x, y)}${isNext ? ", the next target" : ""}`;
}

export function markWords(mark) {
  if (!mark) return "You have not marked the robot yet.";
  const heading = mark.heading === null || mark.heading === undefined ? "" : `, facing ${facing(mark.heading)}`;
  return `Your mark of the robot: ${at(mark.x, mark.y)}${heading}.`;
}
