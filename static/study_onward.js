// The end page takes the participant on to the panel's completion address with their code, after
// a countdown they can stop ("Stay on this page"): a timed move they cannot hold back would fail
// those who read slowly (WCAG 2.2.1, as axe checks a meta refresh).
import { t } from "./i18n.js";

const link = document.getElementById("completion-link");
const shown = document.getElementById("onward-countdown");
const stay = document.getElementById("stay");
let left = Number(link.dataset.afterS);

const tick = () => {
  if (left <= 0) {
    window.location.assign(link.href);
    return;
  }
  shown.textContent = t("Taking you there in {seconds} s.", { seconds: left });
  left -= 1;
};
const timer = setInterval(tick, 1000);
tick();
stay.hidden = false;
stay.addEventListener("click", () => {
  clearInterval(timer);
  shown.textContent = t("You stay here; the link above takes you there when you are ready.");
  stay.hidden = true;
});
