// Table frame <-> map pixels, as sim/core/geometry.py maps them (1401 x 1175 px for 2.4638 m x 2.0574 m).
export const TableMap = {
  W_M: 2.4638, H_M: 2.0574, W_PX: 1401, H_PX: 1175,
  toWorld(canvas, cx, cy) {
    const col = cx / canvas.width * (this.W_PX - 1), row = cy / canvas.height * (this.H_PX - 1);
    return {x: col / (this.W_PX - 1) * this.W_M, y: (1 - row / (this.H_PX - 1)) * this.H_M};
  },
  toCanvas(canvas, x, y) {
    return {cx: x / this.W_M * canvas.width, cy: (1 - y / this.H_M) * canvas.height};
  },
  clamp(x, y) {
    return {x: Math.min(Math.max(x, 0), this.W_M), y: Math.min(Math.max(y, 0), this.H_M)};
  },
  drawRobot(ctx, canvas, x, y, heading, colour, {dashed = false} = {}) {
    const {cx, cy} = this.toCanvas(canvas, x, y);
    ctx.save();
    ctx.fillStyle = colour; ctx.strokeStyle = colour; ctx.lineWidth = 3;
    if (dashed) { ctx.setLineDash([4, 3]); ctx.fillStyle = "transparent"; }
    ctx.beginPath(); ctx.arc(cx, cy, 9, 0, 2 * Math.PI);
    if (dashed) ctx.stroke(); else ctx.fill();
    if (heading !== null && heading !== undefined) {
      ctx.beginPath(); ctx.moveTo(cx, cy);
      ctx.lineTo(cx + 24 * Math.cos(heading), cy - 24 * Math.sin(heading)); ctx.stroke();
    }
    ctx.restore();
  },
  // A bold ring and the word "next" at the landmark the team is looking for now.
  drawTargetMark(ctx, canvas, x, y) {
    const {cx, cy} = this.toCanvas(canvas, x, y);
    ctx.save();
    ctx.lineWidth = 5; ctx.strokeStyle = "#000";
    ctx.beginPath(); ctx.arc(cx, cy, 27, 0, 2 * Math.PI); ctx.stroke();
    ctx.lineWidth = 3; ctx.strokeStyle = "#fff"; ctx.setLineDash([7, 4]);
    ctx.beginPath(); ctx.arc(cx, cy, 27, 0, 2 * Math.PI); ctx.stroke();
    ctx.setLineDash([]);
    ctx.font = "bold 15px system-ui, sans-serif"; ctx.textAlign = "center";
    const ty = cy - 33 < 14 ? cy + 46 : cy - 33;
    ctx.lineWidth = 4; ctx.strokeStyle = "#000"; ctx.strokeText("next", cx, ty);
    ctx.fillStyle = "#fff"; ctx.fillText("next", cx, ty);
    ctx.restore();
  },
};

// An image that is shown only once it has loaded (never a broken-image placeholder).
export function showImage(img, src, onFail = () => {}) {
  if (!src) { img.hidden = true; img.removeAttribute("src"); return; }
  img.onload = () => { img.hidden = false; };
  img.onerror = () => { img.hidden = true; onFail(); };
  img.src = src;
}

// The CSRF token the server put in the page, for every state-changing request.
// Headings (radians in events, counter-clockwise from +x) as the UI shows them: whole degrees
// in -180..180, for the simulator and the rover alike.
export function headingDegrees(rad) {
  const deg = Math.round(rad * 180 / Math.PI);
  return ((deg + 180) % 360 + 360) % 360 - 180 || 0;
}

export function csrfHeaders() {
  const meta = document.querySelector('meta[name="csrf-token"]');
  return meta && meta.content ? {"X-CSRF-Token": meta.content} : {};
}
