// The study lobby: ask the server about once a second; it pairs us when a partner waits, then
// this page opens our seat. Leaving (the button, or the page closing) tells the server at once,
// so nobody is paired with us once we have gone. Being paired raises an alert (title, beep, the
// partner's seat) a moment before the seat opens, for one who looked away while waiting.
import { beep, raise, unlockSound } from "./alert.js";
import { t } from "./i18n.js";

const lobby = document.getElementById("lobby");
const status = document.getElementById("lobby-status");
const csrf = document.querySelector('meta[name="csrf-token"]').content;
const url = `/study/${encodeURIComponent(lobby.dataset.study)}/lobby`;
let gone = false;  // seated, or left by the button: nothing to tell as the page closes
const SEATS = { commander: t("the Commander (you see the map)"), driver: t("the Driver (you see the camera and move)") };
const OPEN_SEAT_AFTER_MS = 2000;  // the alert is seen and heard before the seat page replaces it

document.getElementById("sound-on").addEventListener("click", async (event) => {
  await unlockSound();
  event.target.textContent = beep() ? t("Sound is on") : t("Sound is blocked by this browser");
});

document.getElementById("leave-lobby").addEventListener("submit", () => { gone = true; });
window.addEventListener("pagehide", () => {
  if (gone) return;
  const form = new FormData();
  form.append("csrf_token", csrf);
  navigator.sendBeacon(`${url}/leave`, form);
});

async function poll() {
  let state;
  try {
    const reply = await fetch(url, { method: "POST", headers: { "X-CSRF-Token": csrf } });
    if (reply.status === 429) {  // over the lobby's rate: the server says when; ask again then
      status.textContent = t("Please wait: {why}.", { why: (await reply.json()).detail });
      setTimeout(poll, 1000 * Number(reply.headers.get("Retry-After") || 2));
      return;
    }
    if (!reply.ok) throw new Error((await reply.json()).detail || reply.statusText);
    state = await reply.json();
  } catch (err) {
    status.textContent = t("Cannot reach the server ({why}); retrying…", { why: err.message });
    setTimeout(poll, 2000);
    return;
  }
  if (state.state === "seated") {
    const partner = state.role === "commander" ? "driver" : "commander";
    status.textContent = t("Paired! You are {seat}; your partner is {partner}. Opening your trial…",
      { seat: SEATS[state.role], partner: SEATS[partner] });
    lobby.dataset.seat = state.role;
    lobby.dataset.partnerSeat = partner;
    raise(t("Paired!"));
    gone = true;
    setTimeout(() => window.location.assign(state.link), OPEN_SEAT_AFTER_MS);
  } else if (state.state === "all_played") {
    status.textContent = t("You have played all {trials} of your trials. Answer the last questionnaire and get your completion code on your page.",
      { trials: state.trials });
  } else if (state.state === "timed_out" || state.state === "ended") {
    // The end of the way, recorded already: its page gives the outcome's code.
    status.textContent = state.state === "timed_out"
      ? t("Nobody arrived within {minutes} minutes. Thank you for waiting: your completion code is next.",
        { minutes: Math.round(state.waited_s / 60) })
      : t("Your part in the study has ended. Your completion code is next.");
    gone = true;
    setTimeout(() => window.location.assign(state.next), 3000);
  } else {
    const others = state.waiting - 1;
    status.textContent = others ? t("Others waiting: {others}. Pairing…", { others })
      : t("You are the only one waiting. A partner will be found as soon as one arrives.");
    lobby.dataset.waiting = String(state.waiting);
    setTimeout(poll, 1000);
  }
}
poll();
