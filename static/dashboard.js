// Experimenter dashboard: every open trial's phase, clock, moves and seats once a second, and a
// small top-down view with the true pose for each running trial.
"use strict";
(() => {
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
    if (image.complete) ctx.drawImage(image, 0, 0, canvas.width, canvas.height);
    if (t.localization) TableMap.drawRobot(ctx, canvas, t.localization.x, t.localization.y, t.localization.heading, "#ff8c00");
    if (t.pose) TableMap.drawRobot(ctx, canvas, t.pose[0], t.pose[1], t.pose[2], "#1e6bff");
    const seats = Object.entries(t.seats).map(([r, on]) => `${r} ${on ? "●" : "○"}`).join(" ");
    caption.textContent = `#${t.trial_id} ${t.maze} · ${t.phase}${t.target ? " → " + t.target : ""}` +
      `${t.paused.length ? " (paused)" : ""} · ${t.elapsed_s.toFixed(0)} s · ${t.moves} moves · ${seats}`;
  }

  async function refresh() {
    let trials;
    try {
      const res = await fetch("/experimenter/api/trials", {credentials: "same-origin"});
      if (!res.ok) return;
      trials = (await res.json()).trials;
    } catch (e) { return; }  // the next tick retries
    const running = new Set();
    for (const t of trials) {
      const row = document.querySelector(`tr[data-trial="${t.trial_id}"]`);
      if (row) {
        row.querySelector(".phase").textContent = t.phase + (t.paused.length ? " (paused)" : "");
        const seats = Object.entries(t.seats).map(([r, on]) => `${r} ${on ? "●" : "○"}`).join(" ");
        row.querySelector(".live").textContent = `${t.elapsed_s.toFixed(0)} s · ${t.moves} moves · ${seats}`;
      }
      if (t.phase !== "finished" && t.phase !== "aborted") { running.add(t.trial_id); drawLive(t); }
    }
    for (const id of Object.keys(maps)) {
      if (!running.has(Number(id))) { maps[id].card.remove(); delete maps[id]; }
    }
    document.getElementById("live-empty").hidden = running.size > 0;
  }
  setInterval(refresh, 1000); refresh();
})();
