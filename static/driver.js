// Driver: the live camera, moves (buttons and arrow keys) and "I found the target".
import {$, on, send, showError} from "./seat.js";
import {showImage} from "./maputil.js";
import {friendlyError, isRunning} from "./trial.js";

const KEYS = {ArrowUp: "forward", ArrowLeft: "left", ArrowRight: "right"};
const MOVE_TIMEOUT_MS = 5000;  // a move whose result never came (e.g. the server restarted)
let pending = null, pendingSince = 0;
const note = (text) => { $("move-note").textContent = text; };

// The camera is busy while a move waits for its result (assistive technology, and scripts, can tell).
function setPending(id) {
  pending = id;
  $("camera").setAttribute("aria-busy", String(id !== null));
}

function move(action) {
  if (pending && performance.now() - pendingSince < MOVE_TIMEOUT_MS) { note("Wait: the robot is still moving."); return; }
  setPending(Math.random().toString(36).slice(2, 10));
  pendingSince = performance.now();
  if (!send("move", {action, move_id: pending})) setPending(null);
}
["forward", "left", "right"].forEach((a) => $(a).addEventListener("click", () => move(a)));
document.addEventListener("keydown", (ev) => {
  if (ev.target.tagName === "INPUT" || ev.target.tagName === "TEXTAREA" || !KEYS[ev.key]) return;
  ev.preventDefault(); move(KEYS[ev.key]);
});
$("found").addEventListener("click", () => send("claim"));

function camera(jpeg) { showImage($("camera"), `data:image/jpeg;base64,${jpeg}`); $("camera-wait").hidden = true; }

on("welcome", (msg) => { setPending(null); if (msg.frame) camera(msg.frame.jpeg); });
on("frame", (msg) => camera(msg.jpeg));
on("status", (s) => {
  // Buttons follow the trial: moves and claims only while it runs and no claim awaits the Commander.
  const live = isRunning(s) && !s.claim_pending;
  ["forward", "left", "right"].forEach((a) => { $(a).disabled = !live; });
  $("found").disabled = !(live && s.phase === "navigating");
  if (s.phase === "finished") { note("All three targets found. Well done!"); showError(""); }
  else if (s.phase === "aborted") { note(""); showError(""); }
});
on("move_executed", (msg) => {
  const p = msg.payload;
  if (p.move_id === pending) setPending(null);
  note(p.outcome === "collision" ? "Bump! Something is in the way."
    : p.outcome === "refused" ? friendlyError(p.reason) : "");
});
// Refused as it was asked for (too soon, paused, one still executing): nothing moved.
on("move_refused", (msg) => {
  if (msg.move_id === pending) setPending(null);
  note(friendlyError(msg.reason));
});
// Over the seat's rate the move was dropped unanswered: a press after the pause may go.
on("error", (msg) => { if (msg.code === "rate_limited") setPending(null); });
on("target_claimed", () => note("Waiting for the Commander to confirm…"));
// A decision answers the claim: a refusal shown while it was pending no longer applies.
on("target_confirmed", () => { note("Confirmed! On to the next target."); showError(""); });
on("target_rejected", () => { note("The Commander says that is not it. Keep looking."); showError(""); });
