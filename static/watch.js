// The experimenter's view of one trial over its watch socket (/ws/watch/ID): status, clock and
// moves, the full map with the true pose and the Commander's estimate, and the Driver's live
// camera. Controls follow the trial's state.
import {headingDegrees, showImage, TableMap} from "./maputil.js";
import {confirmFirst, showControls} from "./controls.js";
import {drawLDHBelief} from "./ldh_belief.js";
import {applyStatus, clockSeconds, emptyStatus, formatClock, OVER, statusText} from "./trial.js";

const root = document.getElementById("watch");
const id = Number(root.dataset.trial);
const $ = (x) => document.getElementById(x);
const canvas = $("truth"), ctx = canvas.getContext("2d");
const map = new Image();
const status = Object.assign(emptyStatus(), {phase: root.dataset.phase, targets_total: Number(root.dataset.targets),
                                             elapsed_s: Number(root.dataset.elapsed), moves: Number(root.dataset.moves)});
const seen = {pose: null, localization: null, ldh: null, belief: null};
let announced = "", retryMs = 500;
map.src = `/experimenter/trials/${id}/map.png`;

function draw() {
  if (map.complete && map.naturalWidth) ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
  const est = seen.localization, pose = seen.pose;
  // The LDH model's discs, and their caption, only while the Commander is localizing.
  const ldh = status.phase === "localizing" && seen.ldh && seen.ldh.length > 0;
  if (ldh) drawLDHBelief(ctx, canvas, seen.ldh);
  $("ldh-note").hidden = !ldh;
  if (seen.belief) drawBelief(seen.belief);
  if (est) TableMap.drawRobot(ctx, canvas, est.x, est.y, est.heading, "#ff8c00");
  if (pose) {
    TableMap.drawRobot(ctx, canvas, pose[0], pose[1], pose[2], "#1e6bff");
    $("pose-note").textContent = `True pose: x ${pose[0].toFixed(2)} m, y ${pose[1].toFixed(2)} m, ` +
      `heading ${headingDegrees(pose[2])}°`;
  }
}

// The particle filter's belief: weighted points and their mean, in teal (experimenter only).
function drawBelief(b) {
  const wmax = Math.max(...b.points.map((p) => p[2]));
  ctx.fillStyle = "#00a080";
  for (const [x, y, w] of b.points) {
    const {cx, cy} = TableMap.toCanvas(canvas, x, y);
    ctx.globalAlpha = 0.25 + 0.75 * w / wmax;
    ctx.fillRect(cx - 1.5, cy - 1.5, 3, 3);
  }
  ctx.globalAlpha = 1;
  TableMap.drawRobot(ctx, canvas, b.mean[0], b.mean[1], b.mean[2], "#00a080");
}

const targets = root.dataset.targetNames.split(",");
const penalty = Number(root.dataset.penalty);
let claimPending = null;

function addChat(p) {
  const li = document.createElement("li");
  li.className = p.role;
  const who = document.createElement("b");
  who.textContent = p.role === "commander" ? "Commander" : "Driver";
  li.append(who, document.createTextNode(" " + p.text));
  $("messages").append(li);
}

// A claim waits for the Commander's verdict; the verdict clears it (with the ground truth, ours only).
const pendingText = (i) => `Claim pending: the Driver says target ${i + 1} (${targets[i]}) is here.`;
function onClaimEvent(kind, p) {
  if (kind === "target_claimed") claimPending = pendingText(p.target_index);
  else if (kind === "target_confirmed" || kind === "target_rejected") {
    const truth = p.within_m === undefined ? "" : ` (truly ${p.truly_within ? "within" : "not within"} reach, ${Number(p.within_m).toFixed(2)} m)`;
    claimPending = null;
    $("claim-note").dataset.last = `${kind === "target_confirmed" ? "Confirmed" : "Rejected"}${truth}.`;
    // A line of the chat too, where it came in the dialog (at the top alone, it read out of order).
    const name = p.target || targets[p.target_index];
    addNote(`${kind === "target_confirmed" ? "Confirmed" : "Rejected"}: target ${p.target_index + 1} (${name})${truth}.`);
  }
}

function addNote(text) {
  const li = document.createElement("li");
  li.className = "note";
  li.textContent = text;
  $("messages").append(li);
}

function render() {
  const over = OVER.has(status.phase);
  $("next-target").textContent = over ? "—" : (targets[Math.min(status.target_index, targets.length - 1)] || "…");
  const note = $("claim-note");
  note.textContent = claimPending || note.dataset.last || "";
  note.hidden = !note.textContent;
  // The leaderboard's score, once the trial has finished: time plus the penalty per move.
  $("score-box").hidden = status.phase !== "finished";
  if (status.phase === "finished" && status.moves !== null) {
    $("score").textContent = `${(clockSeconds(status) + penalty * status.moves).toFixed(1)} s`;
  }
  const text = statusText(status, "experimenter");
  if (text !== announced) { $("status").textContent = text; announced = text; }
  $("status").dataset.phase = status.phase;
  $("clock").textContent = formatClock(clockSeconds(status));
  if (status.moves !== null) $("moves").textContent = String(status.moves);
  showControls($("controls"), status.phase, status.paused);
}

function camera(jpeg) {
  showImage($("camera"), `data:image/jpeg;base64,${jpeg}`);
  $("camera-wait").hidden = true;
}

function onMessage(msg) {
  if (msg.type === "welcome") {
    applyStatus(status, msg.status);
    seen.pose = msg.pose; seen.localization = msg.localization;
    $("messages").replaceChildren();
    msg.history.forEach((e) => { if (e.kind === "chat") addChat(e.payload); else onClaimEvent(e.kind, e.payload); });
    if (msg.pending_claim) claimPending = pendingText(status.target_index);
    if (msg.frame) camera(msg.frame.jpeg);
  } else if (msg.type === "belief") {
    seen.belief = msg;
  } else if (msg.type === "ldh_belief") {
    seen.ldh = msg.top;
    $("ldh-note").textContent = `LDH belief (${msg.model}), after the dialog so far: violet discs, larger where likelier.`;
  } else if (msg.type === "status") {
    applyStatus(status, msg);
  } else if (msg.type === "event") {
    if (msg.kind === "frame" && msg.jpeg) camera(msg.jpeg);
    else if (msg.kind === "pose") seen.pose = [msg.payload.x, msg.payload.y, msg.payload.heading];
    else if (msg.kind === "localization") seen.localization = msg.payload;
    else if (msg.kind === "chat") addChat(msg.payload);
    else onClaimEvent(msg.kind, msg.payload);
  }
  render(); draw();
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${scheme}://${location.host}/ws/watch/${id}`);
  ws.onopen = () => { retryMs = 500; };
  ws.onmessage = (e) => onMessage(JSON.parse(e.data));
  ws.onclose = () => {  // a server restart or a dropped link: watch again, unless the trial is over
    if (OVER.has(status.phase)) return;
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 8000);
  };
}

confirmFirst(document);
map.onload = draw;
setInterval(render, 250);
render();
connect();
