// Driver: the live camera, moves (buttons and arrow keys) and "I found the target".
import {$, on, send, showError} from "./seat.js";
import {showImage} from "./maputil.js";
import {friendlyError, isRunning} from "./trial.js";
import {t} from "./i18n.js";

const KEYS = {ArrowUp: "forward", ArrowLeft: "left", ArrowRight: "right"};
const WORDS = {forward: t("forward"), left: t("left"), right: t("right")};
const MOVE_TIMEOUT_MS = 5000;  // a move whose result never came (e.g. the server restarted)
const MARGIN_MS = 100;  // on top of the server's interval: a loaded server may take the last move up to this late
const minIntervalMs = 1000 * Number($("seat").dataset.minMoveIntervalS || 0);
// One move at a time: `pending` is the move in flight; one press made meanwhile (or sooner after the
// last move than the server takes one) waits in `queued` and goes once the server would take it.
let pending = null, pendingAction = null, pendingSince = -Infinity, queued = null, timer = null;
const note = (text) => { $("move-note").textContent = text; };
// Presses in a row that bumped: a person pressing Forward as often as told could not tell how many
// had moved the robot, and reported a walk done that never began.
let bumps = 0;
function bumped(collided) {
  bumps = collided ? bumps + 1 : 0;
  $("seat").dataset.bumped = String(collided);
  if (!collided) return "";
  // Each still counts as a move: a person who saw the count rise took a bump for a step made.
  return bumps > 1 ? t("Bump! Something is in the way: the last {n} presses did not move the robot (each still counts as a move).", {n: bumps})
    : t("Bump! Something is in the way. The press still counts as a move.");
}

function showProgress() {
  const moving = pending !== null;
  // The camera is busy while a move waits for its result (assistive technology, and scripts, can tell).
  $("camera").setAttribute("aria-busy", String(moving));
  $("seat").dataset.moving = String(moving);
  $("seat").dataset.queued = queued || "";
  $("move-progress").hidden = !moving && !queued;
  $("move-progress").textContent = moving ? (queued ? t("Moving {way}… then {next}.", {way: WORDS[pendingAction], next: WORDS[queued]})
    : t("Moving {way}…", {way: WORDS[pendingAction]})) : queued ? t("Next: {way}.", {way: WORDS[queued]}) : "";
}

function sendMove(action) {
  pending = Math.random().toString(36).slice(2, 10);
  pendingAction = action;
  pendingSince = performance.now();
  if (!send("move", {action, move_id: pending})) pending = null;
  showProgress();
}

// Send the queued press once nothing is in flight and the server's interval since the last move has passed.
function drain() {
  clearTimeout(timer);
  if (!queued || pending !== null) return;
  const wait = pendingSince + minIntervalMs + MARGIN_MS - performance.now();
  if (wait > 0) { timer = setTimeout(drain, wait); return; }
  const action = queued;
  queued = null;
  sendMove(action);
}

function move(action) {
  if (pending !== null && performance.now() - pendingSince > MOVE_TIMEOUT_MS) pending = null;  // its result is lost
  if (queued) { note(t("Wait: the robot is still moving, and your next move is queued.")); return; }
  queued = action;
  drain();
  showProgress();
}

function dropQueue() { queued = null; clearTimeout(timer); showProgress(); }

["forward", "left", "right"].forEach((a) => $(a).addEventListener("click", () => move(a)));
document.addEventListener("keydown", (ev) => {
  if (ev.target.tagName === "INPUT" || ev.target.tagName === "TEXTAREA" || !KEYS[ev.key]) return;
  ev.preventDefault();
  if (!ev.repeat) move(KEYS[ev.key]);  // a held key is one press: the browser's repeats are not moves
});
$("found").addEventListener("click", () => send("claim"));

function camera(jpeg) { showImage($("camera"), `data:image/jpeg;base64,${jpeg}`); $("camera-wait").hidden = true; }

on("welcome", (msg) => { pending = null; dropQueue(); if (msg.frame) camera(msg.frame.jpeg); });
on("frame", (msg) => camera(msg.jpeg));
on("status", (s) => {
  // Buttons follow the trial: moves and claims only while it runs and no claim awaits the Commander.
  const live = isRunning(s) && !s.claim_pending;
  ["forward", "left", "right"].forEach((a) => { $(a).disabled = !live; });
  if (!live) dropQueue();  // a press queued before a pause or a claim is not carried past it
  $("found").disabled = !(live && s.phase === "navigating");
  if (s.phase === "finished") { note(t("All three targets found. Well done!")); showError(""); }
  else if (s.phase === "aborted") { note(""); showError(""); }
});
on("move_executed", (msg) => {
  const p = msg.payload;
  if (p.move_id !== pending) return;  // not this page's (another window of the seat), or given up on
  pending = null;
  if (p.outcome === "refused") dropQueue();
  note(p.outcome === "refused" ? friendlyError(p.reason) : bumped(p.outcome === "collision"));
  showProgress();
  drain();
});
// Refused as it was asked for (too soon, paused, one still executing): nothing moved.
on("move_refused", (msg) => {
  if (msg.move_id === pending) { pending = null; dropQueue(); }
  note(friendlyError(msg.reason));
});
// Over the seat's rate the move was dropped unanswered: a press after the pause may go.
on("error", (msg) => { if (msg.code === "rate_limited") { pending = null; showProgress(); drain(); } });
on("target_claimed", () => note(t("Waiting for the Commander to confirm…")));
// A decision answers the claim: a refusal shown while it was pending no longer applies.
on("target_confirmed", () => { note(t("Confirmed! On to the next target.")); showError(""); });
on("target_rejected", () => { note(t("The Commander says that is not it. Keep looking.")); showError(""); });
