// Commander: the walls-only map with the "robot is here" tool, the next target's image, claims.
"use strict";
(() => {
  const {$, on, send, token} = Seat;
  const canvas = $("map"), ctx = canvas.getContext("2d");
  const map = new Image();
  let estimate = null, press = null;
  map.onload = draw;
  map.src = `/play/${encodeURIComponent(token)}/map.png`;

  function draw() {
    ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
    if (estimate) TableMap.drawRobot(ctx, canvas, estimate.x, estimate.y, estimate.heading, "#ff8c00");
  }

  function point(ev) {
    const r = canvas.getBoundingClientRect();
    return {cx: (ev.clientX - r.left) * canvas.width / r.width, cy: (ev.clientY - r.top) * canvas.height / r.height};
  }
  canvas.addEventListener("mousedown", (ev) => { press = point(ev); });
  canvas.addEventListener("mouseup", (ev) => {
    if (!press) return;
    const up = point(ev), at = TableMap.toWorld(canvas, press.cx, press.cy);
    const dx = up.cx - press.cx, dy = up.cy - press.cy;
    const heading = Math.hypot(dx, dy) > 8 ? Math.atan2(-dy, dx) : null;  // canvas y points down
    press = null;
    const x = Math.min(Math.max(at.x, 0), TableMap.W_M), y = Math.min(Math.max(at.y, 0), TableMap.H_M);
    if (send("localize", {x, y, heading})) { estimate = {x, y, heading}; draw(); }
  });

  function showTarget(name, index) {
    $("target-name").textContent = name || "—";
    if (name) $("target-image").src = `/play/${encodeURIComponent(token)}/target/${index}.jpg`;
  }
  function showClaim(claim) {
    if (!claim) { $("claim").classList.add("hidden"); return; }
    $("claim-image").src = claim.jpeg ? `data:image/jpeg;base64,${claim.jpeg}` : "";
    $("claim").classList.remove("hidden");
  }

  on("welcome", (msg) => { showTarget(msg.target, msg.target_index); showClaim(msg.claim || null); });
  on("phase", (msg) => {
    if (msg.target) showTarget(msg.target, msg.payload.target_index);
    if (msg.payload.phase === "finished") { $("target-name").textContent = "all three found!"; }
    $("map-hint").textContent = msg.payload.phase === "localizing"
      ? "Click where you think the robot is (drag to give its heading)." : "You can mark the robot again at any time.";
  });
  on("localization", (msg) => { estimate = msg.payload; draw(); });
  on("target_claimed", (msg) => showClaim(msg.claim));
  on("target_confirmed", () => showClaim(null));
  on("target_rejected", () => showClaim(null));
  $("confirm").addEventListener("click", () => send("confirm"));
  $("reject").addEventListener("click", () => send("reject"));
})();
