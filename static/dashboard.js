// Experimenter dashboard: live phase, clock, moves and seats of every open trial, once a second.
"use strict";
(() => {
  async function refresh() {
    try {
      const res = await fetch("/experimenter/api/trials", {credentials: "same-origin"});
      if (!res.ok) return;
      const {trials} = await res.json();
      for (const t of trials) {
        const row = document.querySelector(`tr[data-trial="${t.trial_id}"]`);
        if (!row) continue;
        row.querySelector(".phase").textContent = t.phase + (t.paused.length ? " (paused)" : "");
        const seats = Object.entries(t.seats).map(([r, on]) => `${r} ${on ? "●" : "○"}`).join(" ");
        row.querySelector(".live").textContent = `${t.elapsed_s.toFixed(0)} s · ${t.moves} moves · ${seats}`;
      }
    } catch (e) { /* the next tick retries */ }
  }
  setInterval(refresh, 1000); refresh();
})();
