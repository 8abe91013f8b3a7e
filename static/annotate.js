// The annotation page: the aids (estimates, true trace) can be hidden so they do not lead the annotator.
const toggle = document.getElementById("show-aids");
toggle.addEventListener("change", () => {
  document.body.classList.toggle("aids-hidden", !toggle.checked);
});
