// Drawing a participant back to a page that needs them (paired in the lobby, a claim to judge):
// the tab's title, a short beep and the words on the page. The beep is made here (WebAudio, no
// file); browsers let a page sound only after a click or key press on it, so the audio is started
// by the first one (a "Sound on" button offers one).
let audio = null;
const pageTitle = document.title;

export function unlockSound() {
  audio ??= new AudioContext();
  return audio.resume();
}
for (const kind of ["pointerdown", "keydown"]) window.addEventListener(kind, unlockSound, { capture: true, once: true });

export function beep() {
  if (!audio || audio.state !== "running") return false;
  const now = audio.currentTime;
  const tone = audio.createOscillator();
  const gain = audio.createGain();
  tone.frequency.value = 880;
  gain.gain.setValueAtTime(0.2, now);
  gain.gain.exponentialRampToValueAtTime(0.001, now + 0.35);
  tone.connect(gain).connect(audio.destination);
  tone.start(now);
  tone.stop(now + 0.35);
  return true;
}

// `title` leads the tab's title until `calm()`; `body.dataset.alert` says what was raised and
// `body.dataset.beeped` whether it sounded (the browser tests read them).
export function raise(title) {
  document.title = `${title} · ${pageTitle}`;
  document.body.dataset.alert = title;
  document.body.dataset.beeped = String(beep());
}

export function calm() {
  document.title = pageTitle;
  delete document.body.dataset.alert;
}
