// The study page's live lobby: who waits, how long, and their plan so far, asked every 2 s.
// "Choose" puts a code into the pair-by-hand form (first the empty field, then the second).
const table = document.getElementById("lobby-live");
const form = document.getElementById("pair-by-hand");

function cell(row, text) {
  const td = document.createElement("td");
  td.textContent = text;
  row.append(td);
}

function choose(code) {
  const [a, b] = [form.elements.a, form.elements.b];
  (a.value && a.value !== code ? b : a).value = code;
}

async function refresh() {
  try {
    const res = await fetch(`/experimenter/studies/${table.dataset.study}/lobby`, {credentials: "same-origin"});
    if (!res.ok) return;
    const {waiting} = await res.json();
    const body = table.tBodies[0];
    body.replaceChildren();
    for (const w of waiting) {
      const row = document.createElement("tr");
      row.dataset.code = w.code;
      cell(row, w.code + (w.practice ? " (practice first)" : ""));
      cell(row, `${w.waited_s} s`);
      cell(row, w.teams);
      cell(row, w.commanded);
      cell(row, w.drove);
      const td = document.createElement("td");
      const button = document.createElement("button");
      button.type = "button";
      button.textContent = "Choose";
      button.addEventListener("click", () => choose(w.code));
      td.append(button);
      row.append(td);
      body.append(row);
    }
    if (!waiting.length) {
      const row = document.createElement("tr");
      const td = document.createElement("td");
      td.colSpan = 6;
      td.className = "empty";
      td.textContent = "Nobody waits.";
      row.append(td);
      body.append(row);
    }
  } catch {
    // the next tick tries again
  }
}

if (table) {
  refresh();
  setInterval(refresh, 2000);
}
