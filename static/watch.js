// Experimenter's view of one trial: the full map with the true pose and the Commander's estimate.
"use strict";
(() => {
  const id = Number(document.getElementById("watch").dataset.trial);
  const canvas = document.getElementById("truth"), ctx = canvas.getContext("2d");
  const map = new Image();
  map.src = `/experimenter/trials/${id}/map.png`;
  async function refresh() {
    const res = await fetch("/experimenter/api/trials", {credentials: "same-origin"});
    if (!res.ok) return;
    const t = (await res.json()).trials.find((x) => x.trial_id === id);
    if (map.complete) ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
    if (!t) return;
    document.getElementById("status").textContent =
      `phase ${t.phase}${t.target ? " → " + t.target : ""} · ${t.elapsed_s.toFixed(0)} s · ${t.moves} moves` +
      ` · commander ${t.seats.commander ? "connected" : "away"} · driver ${t.seats.driver ? "connected" : "away"}` +
      (t.paused.length ? ` · paused (${t.paused.join(", ")})` : "");
    if (t.belief) drawBelief(t.belief);
    if (t.localization) TableMap.drawRobot(ctx, canvas, t.localization.x, t.localization.y, t.localization.heading, "#ff8c00");
    if (t.pose) TableMap.drawRobot(ctx, canvas, t.pose[0], t.pose[1], t.pose[2], "#1e6bff");
  }
  // The particle filter's belief: a cloud of weighted points and its mean (experimenter only).
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
  setInterval(refresh, 500); map.onload = refresh;
})();
