// A "Copy" button beside a read-only field (`data-copy`: the field's id) puts its text on the clipboard.
for (const button of document.querySelectorAll("button[data-copy]")) {
  button.addEventListener("click", async () => {
    const field = document.getElementById(button.dataset.copy), said = document.getElementById("copied");
    try { await navigator.clipboard.writeText(field.value); said.textContent = "Copied."; }
    catch (err) { field.select(); said.textContent = "Selected: press Ctrl+C (⌘C) to copy."; }
  });
}
