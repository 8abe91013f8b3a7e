// The experimenter's pause / resume / abort buttons: shown only where they apply (the same rule
// as app/routes/experimenter.py `controls_for`), and abort asks first.
import {OVER} from "./trial.js";

export function controlsFor(phase, paused = []) {
  if (OVER.has(phase)) return [];
  if (phase === "waiting") return ["abort"];
  return [paused.includes("experimenter") ? "resume" : "pause", "abort"];
}

export function showControls(container, phase, paused) {
  const shown = controlsFor(phase, paused);
  for (const action of ["pause", "resume", "abort"]) {
    const form = container.querySelector(`form.control-${action}`);
    if (form) form.hidden = !shown.includes(action);
  }
}

// Forms marked data-confirm submit only once the experimenter says yes.
export function confirmFirst(root) {
  root.addEventListener("submit", (ev) => {
    const question = ev.target.dataset && ev.target.dataset.confirm;
    if (question && !window.confirm(question)) ev.preventDefault();
  });
}
