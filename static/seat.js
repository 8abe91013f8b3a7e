// A seat's socket, shared by the Commander and Driver pages: the token on every message,
// reconnects with back-off, the chat, the trial clock, the move count and the status line
// (announced to screen readers when it changes). Page modules subscribe with on(kind, handler).
import {applyStatus, clockSeconds, emptyStatus, foldEvent, formatClock, friendlyError, joinSecondsLeft, OVER,
        statusText} from "./trial.js";
import {t} from "./i18n.js";
import {thing} from "./mapwords.js";

export const $ = (id) => document.getElementById(id);
const root = $("seat");
export const token = root.dataset.token, role = root.dataset.role;
export const status = emptyStatus();
const after = $("after-trial");  // a study's seat: where its participant goes on (seat_status.html)
const handlers = {};
let ws = null, delay = 500, replaced = false, seatsNeeded = [];

export function on(kind, fn) { (handlers[kind] = handlers[kind] || []).push(fn); }
function emit(kind, msg) { (handlers[kind] || []).forEach((fn) => fn(msg)); }

export function send(type, fields = {}) {
  if (!ws || ws.readyState !== WebSocket.OPEN) { showError(t("Not connected right now; reconnecting…")); return false; }
  ws.send(JSON.stringify({type, token, ...fields}));
  return true;
}

export function showError(text) { $("error").textContent = text; }

function addChat(p) {
  const li = document.createElement("li");
  li.className = p.role;
  const who = document.createElement("b");
  who.textContent = p.role === role ? t("You") : (p.role === "commander" ? t("Commander") : t("Driver"));
  li.append(who, document.createTextNode(" " + p.text));
  $("messages").append(li);
  li.scrollIntoView({block: "nearest"});
}

// A claim's verdict as a line of the chat, in the dialog's order, for both seats (a person who
// pressed Confirm or Reject saw nothing of it there, nor did its partner).
const VERDICTS = {
  target_confirmed: (p) => t("Confirmed: the {thing} is found.", {thing: thing(p.target)}),
  target_rejected: (p) => t("Not confirmed: that is not the {thing} yet.", {thing: thing(p.target)}),
};

function addNote(text) {
  const li = document.createElement("li");
  li.className = "note";
  li.textContent = text;
  $("messages").append(li);
  li.scrollIntoView({block: "nearest"});
}

function addLine(e) {
  if (e.kind === "chat") addChat(e.payload);
  else if (e.kind in VERDICTS) addNote(VERDICTS[e.kind](e.payload));
}

let announced = "";
function renderStatus() {
  const text = statusText(status, role, after ? t("Press Continue to go on.") : undefined);
  $("status").textContent = text;
  $("status").dataset.phase = status.phase;
  document.body.dataset.phase = status.phase;
  const over = OVER.has(status.phase);  // nothing to send once the trial has ended
  $("chat-input").disabled = over;
  $("chat-form").querySelector("button").disabled = over;
  goOn(over);
  if (text !== announced) { $("announce").textContent = text; announced = text; }
  renderClock();
  emit("status", status);
}

// A study's participant goes on once the trial is over. A trial that ended before it began
// (a partner never came) has nothing to look back on: back to the lobby's head on its own.
// An aborted one the experimenter restarts: the page follows to the new trial's seat.
let lastPhase = null, following = false;
function goOn(over) {
  if (!after) return;
  after.hidden = !over;
  if (over && lastPhase === "waiting" && status.phase === "aborted") {
    setTimeout(() => window.location.assign($("continue").href), 3000);
  }
  if (status.phase === "aborted" && !following) { following = true; followRestart(); }
  lastPhase = status.phase;
}

async function followRestart() {
  try {
    const reply = await fetch(after.dataset.follow, {headers: {Accept: "application/json"}});
    if (!reply.ok && reply.status < 500) return;  // no longer in the study (withdrawn): nothing to follow
    const seat = reply.ok ? await reply.json() : {};
    if (seat.link && String(seat.trial_id) !== after.dataset.trial) { window.location.assign(seat.link); return; }
  } catch (err) { /* the server is away for a moment: ask again */ }
  setTimeout(followRestart, 2000);
}

function renderClock() {
  const left = joinSecondsLeft(status), countdown = $("join-countdown");
  countdown.hidden = left === null;
  if (left !== null) {
    $("join-left").textContent = formatClock(Math.ceil(left));
    $("join-left").dataset.seconds = left.toFixed(1);
  }
  $("clock").textContent = formatClock(clockSeconds(status));
  $("clock").dataset.seconds = clockSeconds(status).toFixed(1);
  const moves = $("moves");
  moves.textContent = status.moves === null ? "–" : String(status.moves);
  moves.dataset.moves = status.moves === null ? "" : String(status.moves);
}

function welcome(msg) {
  Object.assign(status, emptyStatus(), {targets_total: msg.targets_total});
  // The fold guesses the clock from what the welcome carries; the server's status, once sent, wins.
  msg.history.forEach((e) => foldEvent(status, e));
  Object.assign(status, {phase: msg.phase, target_index: msg.target_index, paused: msg.paused || [],
                         connected: msg.connected || []});
  seatsNeeded = msg.seats_needed || [];
  status.waiting_for = waitingFor();
  if (msg.status) applyStatus(status, msg.status);
  $("messages").innerHTML = "";
  msg.history.forEach(addLine);
  renderStatus();
  emit("welcome", msg);
}

function waitingFor() {
  if (status.phase !== "waiting") return [];
  return seatsNeeded.filter((r) => !status.connected.includes(r));
}

function handle(msg) {
  switch (msg.type) {
    case "welcome": welcome(msg); return;
    case "status": applyStatus(status, msg); renderStatus(); return;
    case "error": showError(friendlyError(msg.error)); emit("error", msg); return;
    case "replaced": replaced = true; return;
    case "move_refused": emit("move_refused", msg); return;
    case "event": break;
    default: return;
  }
  foldEvent(status, msg);
  if (!status.from_server) status.waiting_for = waitingFor();
  addLine(msg);
  renderStatus();
  emit(msg.kind, msg);
}

function elsewhere(show) {
  $("elsewhere").hidden = !show;
  if (show) { $("status").textContent = t("This seat is open in another window."); $("announce").textContent =
    t("This seat was opened in another window or device."); }
}

function connect() {
  elsewhere(false);
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  ws = new WebSocket(`${scheme}://${location.host}/ws/play?token=${encodeURIComponent(token)}`);
  ws.onopen = () => { delay = 500; showError(""); };
  ws.onmessage = (ev) => handle(JSON.parse(ev.data));
  ws.onclose = (ev) => {
    if (ev.code === 4409 || replaced) { replaced = false; elsewhere(true); return; }
    if (ev.code === 4410) { location.reload(); return; }  // the trial ended: its link's page says so, and where to go on
    if (ev.code === 1008) { showError(friendlyError(ev.reason || "token refused")); return; }
    if (OVER.has(status.phase)) return;
    $("status").textContent = t("Connection lost; reconnecting…");
    setTimeout(connect, delay); delay = Math.min(delay * 2, 8000);
  };
}

$("take-back").addEventListener("click", connect);
$("chat-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  const text = $("chat-input").value.trim();
  if (text && send("chat", {text})) $("chat-input").value = "";
});
setInterval(() => send("ping"), 20000);
setInterval(renderClock, 250);
connect();
