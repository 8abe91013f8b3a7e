// Experimenter dashboard: every open trial's phase, clock, moves and seats once a second, a
// small top-down view with the true pose for each running trial, and each robot's link.
import {csrfHeaders, TableMap} from "./maputil.js";
import {confirmFirst, showControls} from "./controls.js";

const maps = {};  // trial id -> {card, canvas, image}

function liveCard(t) {
  if (maps[t.trial_id]) return maps[t.trial_id];
  const card = document.createElement("figure");
  card.className = "live-trial";
  card.dataset.trial = t.trial_id;
  const canvas = document.createElement("canvas");
  canvas.width = 280; canvas.height = 235;
  const caption = document.createElement("figcaption");
  const link = document.createElement("a");
  link.href = `/experimenter/trials/${t.trial_id}`;
  link.setAttribute("aria-label", `Watch trial ${t.trial_id}`);
  link.append(canvas);
  card.append(link, caption);
  document.getElementById("live").append(card);
  const image = new Image();
  image.src = `/experimenter/trials/${t.trial_id}/map.png`;
  return (maps[t.trial_id] = {card, canvas, caption, image});
}

function drawLive(t) {
  const {canvas, caption, image} = liveCard(t);
  const ctx = canvas.getContext("2d");
  if (image.complete && image.naturalWidth) ctx.drawImage(image, 0, 0, canvas.width, canvas.height);
  if (t.localization) TableMap.drawRobot(ctx, canvas, t.localization.x, t.localization.y, t.localization.heading, "#ff8c00");
  if (t.pose) TableMap.drawRobot(ctx, canvas, t.pose[0], t.pose[1], t.pose[2], "#1e6bff");
  const seats = Object.entries(t.seats).map(([r, on]) => `${r} ${on ? "●" : "○"}`).join(" ");
  caption.textContent = `#${t.trial_id} ${t.maze} · ${phaseText(t)}${t.target ? " → " + t.target : ""}` +
    ` · ${t.elapsed_s.toFixed(0)} s · ${t.moves} moves · ${seats}`;
}

function phaseText(t) {
  if (t.waiting_for.length) return `waiting for ${t.waiting_for.join(", ")}`;
  if (t.paused.includes("disconnect:robot")) return `${t.phase} (paused: robot not connected)`;
  return t.phase + (t.paused.length ? ` (paused${t.pause_note ? `: ${t.pause_note}` : ""})` : "");
}

// -- robots -----------------------------------------------------------------------
function ackText(ack) {
  if (!ack) return "–";
  const what = ack.status === "done" ? "done" : `${ack.status}${ack.reason ? ": " + ack.reason : ""}`;
  return `${ack.action || "move"} ${what}, ${ack.age_s.toFixed(0)} s ago`;
}

function robotRow(r) {
  let row = document.querySelector(`tr[data-robot="${r.id}"]`);
  if (!row) {
    row = document.createElement("tr");
    row.dataset.robot = r.id;
    for (const cls of ["name", "role", "link", "fps", "latency", "ack"]) {
      const td = document.createElement("td");
      td.className = cls;
      row.append(td);
    }
    const remove = document.createElement("button");
    remove.className = "delete";
    remove.dataset.delete = `/experimenter/robots/${r.id}`;
    remove.textContent = "delete";
    remove.setAttribute("aria-label", `Delete robot ${r.name}`);
    row.append(document.createElement("td"));
    row.lastChild.append(remove);
    document.querySelector("#robots tbody").append(row);
  }
  return row;
}

function showRobots(robots) {
  const backend = document.getElementById("backend");
  const empty = document.getElementById("no-robots");
  if (empty) empty.hidden = robots.length > 0;
  for (const r of robots) {
    const row = robotRow(r);
    row.dataset.connected = r.connected;
    row.querySelector(".name").textContent = r.name;
    row.querySelector(".role").textContent = r.role;
    row.querySelector(".link").textContent = r.connected ? "connected" : "not connected";
    row.querySelector(".fps").textContent = r.fps.toFixed(1);
    row.querySelector(".latency").textContent = r.latency_ms === null ? "–" : `${r.latency_ms.toFixed(1)} ms`;
    row.querySelector(".ack").textContent = ackText(r.last_ack);
    if (r.role !== "driver" || !backend) continue;  // no trial form before the first team
    // The trial form names each rover's link, so a trial is not made on an absent one unawares.
    let option = backend.querySelector(`option[value="${r.backend}"]`);
    if (!option) { option = document.createElement("option"); option.value = r.backend; backend.append(option); }
    option.textContent = `${r.name} (rover, ${r.connected ? "connected" : "not connected"})`;
  }
}

document.getElementById("new-robot").addEventListener("submit", async (ev) => {
  ev.preventDefault();
  const form = ev.target, box = document.getElementById("robot-token"), error = document.getElementById("robot-error");
  const res = await fetch(form.action, {method: "POST", body: new FormData(form), credentials: "same-origin",
                                        headers: csrfHeaders()});
  const body = await res.json().catch(() => ({detail: `registration failed (HTTP ${res.status})`}));
  box.hidden = !res.ok;
  error.textContent = res.ok ? "" : (typeof body.detail === "string" ? body.detail : JSON.stringify(body.detail));
  if (!res.ok) return;
  box.querySelector(".name").textContent = body.name;
  box.querySelector(".token").textContent = body.token;
  const role = body.role === "driver" ? "" : ` --role ${body.role}`;
  box.querySelector(".command").textContent = `robotslang-robot --server ${location.origin} --token ${body.token}${role}`;
  form.reset();
  refreshRobots();
});

async function refreshRobots() {
  try {
    const res = await fetch("/experimenter/api/robots", {credentials: "same-origin"});
    if (res.ok) showRobots((await res.json()).robots);
  } catch (e) { /* the next tick retries */ }
}

// An ended trial's join links lead only to a closed page: its replay takes their place, as on reload.
function offerReplay(row) {
  const cell = row.querySelector(".links");
  if (cell.querySelector(".replay")) return;
  const replay = document.createElement("a");
  replay.className = "replay";
  replay.href = `/experimenter/trials/${row.dataset.trial}/replay`;
  replay.textContent = "replay";
  cell.replaceChildren(replay);
}

async function refresh() {
  let trials, phases;
  try {
    const res = await fetch("/experimenter/api/trials", {credentials: "same-origin"});
    if (!res.ok) return;
    ({trials, phases} = await res.json());
  } catch (e) { return; }  // the next tick retries
  // Rows of trials no longer open here show their recorded phase and only the controls that apply.
  const open = new Set(trials.map((t) => String(t.trial_id)));
  for (const row of document.querySelectorAll("tr[data-trial]")) {
    const phase = phases[row.dataset.trial];
    if (open.has(row.dataset.trial) || !phase) continue;
    row.querySelector(".phase").textContent = phase;
    showControls(row, phase, []);
    if (phase === "finished" || phase === "aborted") offerReplay(row);
  }
  const running = new Set();
  for (const t of trials) {
    const row = document.querySelector(`tr[data-trial="${t.trial_id}"]`);
    if (row) {
      row.querySelector(".phase").textContent = phaseText(t);
      const seats = Object.entries(t.seats).map(([r, on]) => `${r} ${on ? "●" : "○"}`).join(" ");
      row.querySelector(".live").textContent = `${t.elapsed_s.toFixed(0)} s · ${t.moves} moves · ${seats}`;
      showControls(row, t.phase, t.paused);
    }
    if (t.phase !== "finished" && t.phase !== "aborted") { running.add(t.trial_id); drawLive(t); }
  }
  for (const id of Object.keys(maps)) {
    if (!running.has(Number(id))) { maps[id].card.remove(); delete maps[id]; }
  }
  document.getElementById("live-empty").hidden = running.size > 0;
}
confirmFirst(document);
setInterval(() => { refresh(); refreshRobots(); }, 1000); refresh(); refreshRobots();

// -- deleting what nothing uses: the server refuses (409) naming why, shown above the forms ----
document.addEventListener("click", async (ev) => {
  const button = ev.target.closest("button[data-delete]");
  if (!button) return;
  const res = await fetch(button.dataset.delete, {method: "DELETE", credentials: "same-origin", headers: csrfHeaders()});
  if (res.ok) { location.reload(); return; }
  const body = await res.json().catch(() => ({detail: `delete failed (HTTP ${res.status})`}));
  const error = document.getElementById("error");
  error.textContent = typeof body.detail === "string" ? body.detail : JSON.stringify(body.detail);
  error.hidden = false;
});
