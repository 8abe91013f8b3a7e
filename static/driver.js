// Driver: the live camera, moves (buttons and arrow keys) and "I found the target".
"use strict";
(() => {
  const {$, on, send} = Seat;
  const KEYS = {ArrowUp: "forward", ArrowLeft: "left", ArrowRight: "right"};
  const MOVE_TIMEOUT_MS = 5000;  // a move whose result never came (e.g. the server restarted)
  let pending = null, pendingSince = 0;

  function move(action) {
    if (pending && performance.now() - pendingSince < MOVE_TIMEOUT_MS) {
      $("move-note").textContent = "wait: the robot is still moving"; return;
    }
    pending = Math.random().toString(36).slice(2, 10);
    pendingSince = performance.now();
    if (!send("move", {action, move_id: pending})) pending = null;
  }
  ["forward", "left", "right"].forEach((a) => $(a).addEventListener("click", () => move(a)));
  document.addEventListener("keydown", (ev) => {
    if (ev.target.tagName === "INPUT" || !KEYS[ev.key]) return;
    ev.preventDefault(); move(KEYS[ev.key]);
  });
  $("found").addEventListener("click", () => send("claim"));

  on("welcome", (msg) => { pending = null; if (msg.frame) $("camera").src = `data:image/jpeg;base64,${msg.frame.jpeg}`; });
  on("frame", (msg) => { $("camera").src = `data:image/jpeg;base64,${msg.jpeg}`; });
  on("move_executed", (msg) => {
    const p = msg.payload;
    if (p.move_id === pending) pending = null;
    $("move-note").textContent = p.outcome === "collision" ? "Bump! Something is in the way."
      : p.outcome === "refused" ? `Move refused: ${p.reason}` : "";
  });
  on("target_claimed", () => { $("move-note").textContent = "Waiting for the Commander to confirm…"; });
  on("target_confirmed", () => { $("move-note").textContent = "Confirmed! On to the next target."; });
  on("target_rejected", () => { $("move-note").textContent = "The Commander says that is not it. Keep looking."; });
  on("phase", (msg) => { if (msg.payload.phase === "finished") $("move-note").textContent = "All three targets found. Well done!"; });
})();
