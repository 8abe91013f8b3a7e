// Replay of one recorded trial: one timeline drives the chat, the Driver's frames and the map.
import {TableMap} from "./maputil.js";
import {emptyStatus, foldEvent, formatClock, statusText} from "./trial.js";

{
  const root = document.getElementById("replay");
  const id = Number(root.dataset.trial);
  // The experimenter's replay, or the annotator's (the same log, served under /annotate).
  const base = root.dataset.base || `/experimenter/trials/${id}`;
  const $ = (x) => document.getElementById(x);
  const canvas = $("map"), ctx = canvas.getContext("2d");
  const scrub = $("scrub"), play = $("play"), speed = $("speed");
  const map = new Image();
  map.src = `${base}/map.png`;

  let events = [], rel = [], chatItems = [], now = 0, end = 0, playing = false, last = null;

  // Milliseconds from the first event after the trial was created (set-up time is not replayed).
  function prepare(log) {
    events = log.events;
    const first = events.find((e) => e.kind !== "trial_created") || events[0];
    const t0 = first ? first.t_ns : 0;
    rel = events.map((e) => Math.max(0, (e.t_ns - t0) / 1e6));
    end = rel.length ? rel[rel.length - 1] : 0;
    scrub.max = String(Math.ceil(end));
    const list = $("chat");
    chatItems = [];
    events.forEach((e, i) => {
      if (e.kind !== "chat") return;
      const li = document.createElement("li");
      li.className = `${e.payload.role} hidden`;
      li.dataset.seq = e.seq;
      li.textContent = `${(rel[i] / 1000).toFixed(1)} s · ${e.payload.role}: ${e.payload.text}`;
      list.appendChild(li);
      chatItems.push({li, i});
    });
    // Claims and verdicts: ticks on the timeline, and buttons that go to each (on the pages that
    // have them: the annotator's page plays the same log without).
    const marks = $("marks"), ticks = $("timeline-marks");
    const MARKED = {target_claimed: "claimed", target_confirmed: "confirmed", target_rejected: "rejected"};
    events.forEach((e, i) => {
      if (!marks || !ticks || !(e.kind in MARKED)) return;
      const option = document.createElement("option");
      option.value = String(Math.round(rel[i]));
      ticks.appendChild(option);
      const li = document.createElement("li"), button = document.createElement("button");
      button.type = "button";
      button.className = `mark ${MARKED[e.kind]}`;
      button.textContent = `${(rel[i] / 1000).toFixed(1)} s: target ${e.payload.target_index + 1} ${MARKED[e.kind]}`;
      button.addEventListener("click", () => { setPlaying(false); now = rel[i]; render(); });
      li.appendChild(button);
      marks.appendChild(li);
    });
    // A rover trial's overhead camera, played beside the Driver's.
    if ($("overhead-card")) {
      $("overhead-card").hidden = !events.some((e) => e.kind === "frame" && e.payload.source === "overhead");
    }
  }

  // How many events have happened at `t` ms (binary search over the sorted times).
  function count(t) {
    let lo = 0, hi = rel.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (rel[mid] <= t) lo = mid + 1; else hi = mid; }
    return lo;
  }

  function render() {
    const n = count(now);
    const status = emptyStatus();
    let frame = null, overhead = null, pose = null;
    const trace = [], estimates = [];
    for (let i = 0; i < n; i++) {
      const e = events[i], p = e.payload;
      foldEvent(status, e);
      if (e.kind === "frame" && (p.source || "driver") === "driver") frame = p;
      else if (e.kind === "frame" && p.source === "overhead") overhead = p;
      else if (e.kind === "pose") { pose = p; trace.push(p); }
      else if (e.kind === "localization") estimates.push(p);
    }
    let latest = null;
    for (const {li, i} of chatItems) {
      li.classList.toggle("hidden", i >= n);
      li.classList.remove("latest");
      if (i < n) latest = li;
    }
    if (latest && latest !== render.latest) latest.scrollIntoView({block: "nearest"});
    if (latest) latest.classList.add("latest");
    render.latest = latest;

    const img = $("frame");
    if (frame && img.dataset.frameId !== String(frame.frame_id)) {
      img.src = frame.url; img.dataset.frameId = frame.frame_id; img.hidden = false; $("frame-wait").hidden = true;
      $("frame-info").textContent = `frame ${frame.frame_id}`;
    } else if (!frame && img.dataset.frameId) {
      img.removeAttribute("src"); delete img.dataset.frameId; img.hidden = true; $("frame-wait").hidden = false;
      $("frame-info").textContent = "";
    }

    const top = $("overhead");  // none on the annotator's page
    if (top && overhead && top.dataset.frameId !== String(overhead.frame_id)) {
      top.src = overhead.url; top.dataset.frameId = overhead.frame_id; top.hidden = false;
      $("overhead-info").textContent = `frame ${overhead.frame_id}`;
    } else if (top && !overhead && top.dataset.frameId) {
      top.removeAttribute("src"); delete top.dataset.frameId; top.hidden = true; $("overhead-info").textContent = "";
    }

    if (map.complete && map.naturalWidth) ctx.drawImage(map, 0, 0, canvas.width, canvas.height);
    else { ctx.fillStyle = "#000"; ctx.fillRect(0, 0, canvas.width, canvas.height); }
    if (trace.length > 1) {
      ctx.strokeStyle = "rgba(30,107,255,.85)"; ctx.lineWidth = 3; ctx.beginPath();
      trace.forEach((p, k) => {
        const {cx, cy} = TableMap.toCanvas(canvas, p.x, p.y);
        if (k === 0) ctx.moveTo(cx, cy); else ctx.lineTo(cx, cy);
      });
      ctx.stroke();
    }
    estimates.forEach((p) => TableMap.drawRobot(ctx, canvas, p.x, p.y, p.heading, "#ff8c00"));
    if (pose) TableMap.drawRobot(ctx, canvas, pose.x, pose.y, pose.heading, "#1e6bff");
    canvas.dataset.poses = trace.length;
    canvas.dataset.estimates = estimates.length;

    $("status").textContent = `${statusText(status, "experimenter")} Phase ${status.phase} · trial clock ` +
      `${formatClock(status.active_ns / 1e9)} · ${status.moves || 0} moves · ${status.collisions} collisions · ` +
      `${status.confirmed} target(s) confirmed · event ${n} of ${events.length}`;
    $("clock").textContent = `${(now / 1000).toFixed(1)} s / ${(end / 1000).toFixed(1)} s`;
    scrub.value = String(Math.round(now));
    root.dataset.events = n;
  }

  function tick(ts) {
    if (!playing) return;
    if (last !== null) now = Math.min(end, now + (ts - last) * Number(speed.value));
    last = ts;
    render();
    if (now >= end) { setPlaying(false); return; }
    requestAnimationFrame(tick);
  }

  function setPlaying(on) {
    playing = on;
    play.textContent = on ? "Pause" : "Play";
    play.setAttribute("aria-label", on ? "Pause" : "Play");
    last = null;
    if (on) { if (now >= end) now = 0; requestAnimationFrame(tick); }
  }

  play.addEventListener("click", () => setPlaying(!playing));
  scrub.addEventListener("input", () => { now = Number(scrub.value); render(); });
  document.addEventListener("keydown", (ev) => {
    if (ev.target.tagName === "INPUT" || ev.target.tagName === "SELECT") return;
    if (ev.key === " ") { ev.preventDefault(); setPlaying(!playing); }
  });
  map.onload = render;

  fetch(`${base}/replay.json`, {credentials: "same-origin"})
    .then((res) => { if (!res.ok) throw new Error(`replay log: HTTP ${res.status}`); return res.json(); })
    .then((log) => { prepare(log); root.dataset.ready = "1"; render(); })
    .catch((err) => { $("status").textContent = String(err); });
}
