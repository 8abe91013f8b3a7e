// One trial's status, as every page shows it: the event fold (the same rules as
// app/trial/state.py), the server's `status` message, the trial clock and plain-language texts.
// Shared by the seat pages, the experimenter's trial page and the replay.
import {t} from "./i18n.js";

export const RUNNING = new Set(["localizing", "navigating"]);
export const OVER = new Set(["finished", "aborted"]);

export function emptyStatus() {
  return {phase: "waiting", target_index: 0, targets_total: 3, moves: null, collisions: 0, confirmed: 0,
          paused: [], waiting_for: [], connected: [], active_ns: 0, last_t_ns: null, elapsed_s: 0,
          claim_pending: false, from_server: false};
}

export function isRunning(s) { return RUNNING.has(s.phase) && s.paused.length === 0; }

// One logged event ({kind, t_ns, payload}) folded into the status, as TrialState.apply does.
export function foldEvent(s, e) {
  const p = e.payload || {};
  if (isRunning(s) && s.last_t_ns !== null && e.t_ns !== undefined) s.active_ns += Math.max(0, e.t_ns - s.last_t_ns);
  if (e.t_ns !== undefined) s.last_t_ns = e.t_ns;
  switch (e.kind) {
    case "trial_created": s.targets_total = (p.targets || []).length || s.targets_total; break;
    case "phase":
      s.phase = p.phase;
      if (p.phase === "aborted") s.abort_reason = p.reason || null;
      if (p.target_index !== null && p.target_index !== undefined) s.target_index = p.target_index;
      break;
    case "paused":
      if (!s.paused.includes(p.reason)) s.paused = [...s.paused, p.reason];
      if (p.reason === "experimenter") s.pause_note = p.note || null;
      break;
    case "resumed":
      s.paused = s.paused.filter((r) => r !== p.reason);
      if (p.reason === "experimenter") s.pause_note = null;
      break;
    case "connect": if (!s.connected.includes(p.role)) s.connected = [...s.connected, p.role]; break;
    case "disconnect": s.connected = s.connected.filter((r) => r !== p.role); break;
    case "move_executed":
      if (p.outcome === "ok" || p.outcome === "collision") s.moves = (s.moves || 0) + 1;
      if (p.collision) s.collisions++;
      break;
    case "target_claimed": s.claim_pending = true; break;
    case "target_rejected": s.claim_pending = false; break;
    case "target_confirmed": s.confirmed++; s.claim_pending = false; break;
  }
  if (!s.from_server) s.elapsed_s = s.active_ns / 1e9;
  return s;
}

// The server's status message (or a dashboard snapshot of the same shape) replaces what the fold guessed.
export function applyStatus(s, msg) {
  for (const key of ["phase", "target_index", "targets_total", "elapsed_s", "moves", "paused", "waiting_for", "claim_pending", "abort_reason"])
    if (msg[key] !== undefined && msg[key] !== null) s[key] = msg[key];
  s.join_left_s = msg.join_left_s ?? null;  // null once every seat is open
  s.pause_note = msg.pause_note ?? null;
  s.from_server = true;
  s.status_at = performance.now();
  return s;
}

// Seconds on the trial clock now: the server's figure (or the fold's) advanced locally while running.
export function clockSeconds(s, nowMs = performance.now(), wallNs = Date.now() * 1e6) {
  if (!isRunning(s)) return s.elapsed_s;
  if (s.from_server) return s.elapsed_s + Math.max(0, nowMs - s.status_at) / 1000;
  return (s.active_ns + (s.last_t_ns === null ? 0 : Math.max(0, wallNs - s.last_t_ns))) / 1e9;
}

// Seconds left to open the seats before a study's trial is called off (null: no deadline running).
export function joinSecondsLeft(s, nowMs = performance.now()) {
  if (s.join_left_s === null || s.join_left_s === undefined || s.phase !== "waiting") return null;
  return Math.max(0, s.join_left_s - Math.max(0, nowMs - s.status_at) / 1000);
}

export function formatClock(seconds) {
  const total = Math.max(0, Math.floor(seconds));
  const m = Math.floor(total / 60), sec = total % 60;
  return `${m}:${String(sec).padStart(2, "0")}`;
}

// What is going on, in words a participant (or the experimenter) needs: what to do now.
// `afterwards`: what to do once the trial ended early (a study's seat goes on from the page; the
// experimenter, whose pages are in English, decides what comes next).
const EXPERIMENTER_AFTER = "It does not score. Restart it from the dashboard (the same seats on a layout they have not seen), or exclude it there.";
export function statusText(s, role, afterwards = role === "experimenter" ? EXPERIMENTER_AFTER : t("You can close this page.")) {
  const target = {n: Math.min(s.target_index + 1, s.targets_total), of: s.targets_total};
  if (s.phase === "finished") return t("Finished: all three targets found. Thank you!");
  if (s.phase === "aborted") {
    return s.abort_reason
      ? t("This trial has ended early ({why}). {afterwards}", {why: abortWords(s.abort_reason, role), afterwards})
      : t("This trial has ended early. {afterwards}", {afterwards});
  }
  const missing = s.waiting_for.length ? s.waiting_for
    : (s.paused.filter((r) => r.startsWith("disconnect:")).map((r) => r.slice("disconnect:".length)));
  if (s.phase === "waiting") {
    if (!missing.length) return t("Starting…");
    return t("Waiting for {who} to join.", {who: whom(missing, role)});
  }
  if (s.paused.includes("experimenter")) {
    return s.pause_note
      ? t("Paused by the experimenter ({note}). The clock is stopped.", {note: s.pause_note})
      : t("Paused by the experimenter. The clock is stopped.");
  }
  if (missing.length) {
    return t("Paused: {who} lost the connection. The clock is stopped until they are back.", {who: whom(missing, role)});
  }
  if (s.phase === "localizing") {
    if (role === "commander") return t("Find out where the robot is: ask the Driver what they see, then mark it on the map.");
    if (role === "driver") return t("Tell the Commander what you see, so they can find the robot on the map.");
    return t("Localizing: the Commander is finding the robot on the map.");
  }
  if (s.claim_pending) {
    if (role === "commander") return t("The Driver says they found target {n} of {of}: confirm or reject it.", target);
    if (role === "driver") return t("Waiting for the Commander to confirm your claim.");
    return t("The Driver claims target {n} of {of}: waiting for the Commander to decide.", target);
  }
  if (role === "commander") return t("Guide the Driver to target {n} of {of}.", target);
  if (role === "driver") return t("Drive to target {n} of {of}. Press \"I found the target\" when you see it.", target);
  return t("Navigating to target {n} of {of}.", target);
}

function who(seat, role) {
  if (seat === "robot") return t("the robot");
  if (seat === role) return t("you");
  return seat === "commander" ? t("the Commander") : t("the Driver");
}
const whom = (seats, role) => seats.map((seat) => who(seat, role)).join(t(" and "));

// Why a trial ended early, as the server logs it (sim/trial/decide.py; the experimenter's own words after the colon).
const ABORTS = [
  [/^the (\w+)(?: and the (\w+))? never joined$/, (found, role) => t("{who} never joined",
    {who: whom(found.slice(1).filter(Boolean), role)})],
  [/^the (\w+) was away longer than the grace period$/, (found, role) => t("{who} was away longer than the grace period",
    {who: who(found[1], role)})],
  [/^stopped by the experimenter$/, () => t("stopped by the experimenter")],
  [/^stopped by the experimenter: (.*)$/s, (found) => t("stopped by the experimenter: {said}", {said: found[1]})],
];

function abortWords(reason, role) {
  for (const [pattern, words] of ABORTS) {
    const found = pattern.exec(reason);
    if (found) return words(found, role);
  }
  return reason;
}

// Server error strings to what the participant can do about them (no internal words).
const ERRORS = [
  [/only while navigating/, t("Wait until the Commander has marked where the robot is.")],
  [/previous claim is still waiting/, t("Wait: the Commander is still looking at your last claim.")],
  [/no camera frame/, t("Wait until the camera picture appears.")],
  [/no claimed target/, t("The Driver has not said they found the target yet.")],
  [/still executing|too soon after/, t("Wait: the robot is still moving.")],
  [/robot is not connected/, t("The robot is not connected. Tell the experimenter.")],
  [/waiting for the/, t("Wait until everyone has joined.")],
  [/paused/, t("The trial is paused. Wait until it goes on.")],
  [/cannot mark the robot while/, t("You can mark the robot once the trial has started.")],
  [/the trial is (finished|aborted)/, t("The trial is over.")],
  [/bytes; the limit is|at most \d+ characters|string_too_long/, t("That message is too long. Please shorten it.")],
  [/too many messages/, t("Slow down: that was not sent. Wait a moment and send it again.")],
  [/token|seat/, t("This link no longer works. Ask the experimenter for a new one.")],
  [/server restart/, t("The server restarted. Please try again.")],
];

export function friendlyError(text) {
  for (const [pattern, words] of ERRORS) if (pattern.test(text || "")) return words;
  return t("That did not work. Try again, or tell the experimenter.");
}
