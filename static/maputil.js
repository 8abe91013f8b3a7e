// Table frame <-> map pixels, as sim/geometry.py maps them (1401 x 1175 px for 2.4638 m x 2.0574 m).
"use strict";
const TableMap = {
  W_M: 2.4638, H_M: 2.0574, W_PX: 1401, H_PX: 1175,
  toWorld(canvas, cx, cy) {
    const col = cx / canvas.width * (this.W_PX - 1), row = cy / canvas.height * (this.H_PX - 1);
    return {x: col / (this.W_PX - 1) * this.W_M, y: (1 - row / (this.H_PX - 1)) * this.H_M};
  },
  toCanvas(canvas, x, y) {
    return {cx: x / this.W_M * canvas.width, cy: (1 - y / this.H_M) * canvas.height};
  },
  drawRobot(ctx, canvas, x, y, heading, colour) {
    const {cx, cy} = this.toCanvas(canvas, x, y);
    ctx.fillStyle = colour; ctx.strokeStyle = colour; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.arc(cx, cy, 9, 0, 2 * Math.PI); ctx.fill();
    if (heading !== null && heading !== undefined) {
      ctx.beginPath(); ctx.moveTo(cx, cy);
      ctx.lineTo(cx + 24 * Math.cos(heading), cy - 24 * Math.sin(heading)); ctx.stroke();
    }
  },
};
