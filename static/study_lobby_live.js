// The study page's live lobby: who waits, how long, and their plan so far, asked every 2 s.
// "Choose" puts a code into the pair-by-hand form (first the empty field, then the second).
// Rows are kept and updated in place, not drawn anew each time: a redraw between the press of a
// "Choose" button and its release lost the click.
const table = document.getElementById("lobby-live");
const form = document.getElementById("pair-by-hand");

function choose(code) {
  const [a, b] = [form.elements.a, form.elements.b];
  (a.value && a.value !== code ? b : a).value = code;
}

function newRow(code) {
  const row = document.createElement("tr");
  row.dataset.code = code;
  for (let i = 0; i < 5; i++) row.append(document.createElement("td"));
  const td = document.createElement("td");
  const button = document.createElement("button");
  button.type = "button";
  button.textContent = "Choose";
  button.addEventListener("click", () => choose(code));
  td.append(button);
  row.append(td);
  return row;
}

function fill(row, w) {
  const texts = [w.code + (w.practice ? " (practice first)" : ""), `${w.waited_s} s`, w.teams, w.commanded, w.drove];
  texts.forEach((text, i) => {
    if (row.cells[i].textContent !== String(text)) row.cells[i].textContent = text;
  });
}

function emptyRow() {
  const row = document.createElement("tr");
  const td = document.createElement("td");
  td.colSpan = 6;
  td.className = "empty";
  td.textContent = "Nobody waits.";
  row.append(td);
  return row;
}

async function refresh() {
  try {
    const res = await fetch(`/experimenter/studies/${table.dataset.study}/lobby`, {credentials: "same-origin"});
    if (!res.ok) return;
    const {waiting} = await res.json();
    const body = table.tBodies[0];
    const kept = new Map([...body.rows].filter((r) => r.dataset.code).map((r) => [r.dataset.code, r]));
    waiting.forEach((w, i) => {
      const row = kept.get(w.code) || newRow(w.code);
      kept.delete(w.code);
      fill(row, w);
      if (body.rows[i] !== row) body.insertBefore(row, body.rows[i] || null);
    });
    for (const row of [...body.rows].slice(waiting.length)) row.remove();
    if (!waiting.length) body.append(emptyRow());
  } catch {
    // the next tick tries again
  }
}

if (table) {
  refresh();
  setInterval(refresh, 2000);
}
