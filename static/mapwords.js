// The Commander's map in words, for a screen reader: each wall, landmark and the mark, by the
// ninth of the table it is in (north is the top of the map) and in the metres the keyboard
// cursor moves by (x from the left edge, y from the bottom edge).
import {TableMap} from "./maputil.js";
import {t} from "./i18n.js";

export const COMPASS = ["east", "north-east", "north", "north-west", "west", "south-west", "south", "south-east"];
const FACING = {east: t("facing east"), "north-east": t("facing north-east"), north: t("facing north"),
  "north-west": t("facing north-west"), west: t("facing west"), "south-west": t("facing south-west"),
  south: t("facing south"), "south-east": t("facing south-east")};
const REGION = {"north-west": t("north-west"), north: t("north"), "north-east": t("north-east"), west: t("west"),
  centre: t("centre"), east: t("east"), "south-west": t("south-west"), south: t("south"), "south-east": t("south-east")};
// The maze's things by the server's names (sim/core/labels.py): the landmarks, and the walls by colour.
const THINGS = {jar: t("jar"), mug: t("mug"), paddle: t("paddle")};
const WALLS = {red: t("red wall"), blue: t("blue wall"), green: t("green wall"), brown: t("brown wall"),
  yellow: t("yellow wall"), white: t("white wall")};

export const thing = (name) => THINGS[name] || name;

export function facing(heading) {
  return COMPASS[((Math.round(heading / (Math.PI / 4)) % 8) + 8) % 8];
}
export const facingWords = (heading) => FACING[facing(heading)];

function region(x, y) {
  const col = Math.min(2, Math.floor(3 * x / TableMap.W_M)), row = Math.min(2, Math.floor(3 * y / TableMap.H_M));
  const ns = ["south", "", "north"][Math.max(row, 0)], ew = ["west", "", "east"][Math.max(col, 0)];
  return REGION[ns && ew ? `${ns}-${ew}` : ns || ew || "centre"];
}

const NUMBER = new Intl.NumberFormat(document.documentElement.lang, {minimumFractionDigits: 2, maximumFractionDigits: 2});
export const m = (v) => NUMBER.format(v);
const place = (x, y) => t("the {region} (x {x}, y {y})", {region: region(x, y), x: m(x), y: m(y)});
const at = (x, y) => t("in {place}", {place: place(x, y)});

// A wall as the server describes it (app/map_text.py): straight (its ends), bent (the box it spans) or the table's edge.
export function wallWords({colour, shape, from: [x0, y0], to: [x1, y1]}) {
  const wall = WALLS[colour] || colour;
  if (shape === "edge") return t("{wall} along the table's edge", {wall});
  if (shape === "bent") {
    return t("{wall}, bent, in the {region}, within x {x0} to {x1} and y {y0} to {y1}",
      {wall, region: region((x0 + x1) / 2, (y0 + y1) / 2), x0: m(x0), x1: m(x1), y0: m(y0), y1: m(y1)});
  }
  return t("{wall}, {length} m long, from {start} to {end}",
    {wall, length: m(Math.hypot(x1 - x0, y1 - y0)), start: place(x0, y0), end: place(x1, y1)});
}

export function landmarkWords(name, [x, y], isNext) {
  return isNext ? t("{thing} {at}, the next target", {thing: thing(name), at: at(x, y)})
    : t("{thing} {at}", {thing: thing(name), at: at(x, y)});
}

export function markWords(mark) {
  if (!mark) return t("You have not marked the robot yet.");
  if (mark.heading === null || mark.heading === undefined) return t("Your mark of the robot: {at}.", {at: at(mark.x, mark.y)});
  return t("Your mark of the robot: {at}, {facing}.", {at: at(mark.x, mark.y), facing: facingWords(mark.heading)});
}
