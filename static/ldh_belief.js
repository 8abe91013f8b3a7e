// The LDH model's belief on the experimenter's map: a violet disc per likely node, its area
// proportional to the node's probability (the likeliest one ringed).
import {TableMap} from "./maputil.js";

export function drawLDHBelief(ctx, canvas, top) {
  if (!top || !top.length) return;
  const pMax = Math.max(...top.map(([, , p]) => p));
  ctx.save();
  top.forEach(([x, y, p], i) => {
    const {cx, cy} = TableMap.toCanvas(canvas, x, y);
    ctx.beginPath(); ctx.arc(cx, cy, 3 + 11 * Math.sqrt(p / pMax), 0, 2 * Math.PI);
    ctx.fillStyle = "rgba(150, 40, 220, 0.45)"; ctx.fill();
    if (i === 0) { ctx.lineWidth = 2; ctx.strokeStyle = "#5b0a99"; ctx.stroke(); }
  });
  ctx.restore();
}
