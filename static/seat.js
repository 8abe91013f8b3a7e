// A seat's socket: token on every message, reconnect with back-off, chat and status shared by
// the Commander and Driver pages. Page scripts subscribe with Seat.on(kind, handler).
"use strict";
const Seat = (() => {
  const root = document.getElementById("seat");
  const token = root.dataset.token, role = root.dataset.role;
  const handlers = {};
  let ws = null, delay = 500, lastSeq = 0, state = {phase: "waiting", connected: [], paused: []};
  const $ = (id) => document.getElementById(id);

  function on(kind, fn) { (handlers[kind] = handlers[kind] || []).push(fn); }
  function emit(kind, msg) { (handlers[kind] || []).forEach((fn) => fn(msg)); }

  function send(type, fields = {}) {
    if (!ws || ws.readyState !== WebSocket.OPEN) { showError("not connected; retrying…"); return false; }
    ws.send(JSON.stringify({type, token, ...fields}));
    return true;
  }

  function showError(text) { $("error").textContent = text; }

  function addChat(p) {
    const li = document.createElement("li");
    li.className = p.role;
    const who = document.createElement("b");
    who.textContent = p.role === role ? "You" : (p.role === "commander" ? "Commander" : "Driver");
    li.append(who, document.createTextNode(" " + p.text));
    $("messages").append(li);
    li.scrollIntoView({block: "nearest"});
  }

  function renderStatus() {
    const partner = role === "commander" ? "driver" : "commander";
    let text = state.phase;
    if (state.phase === "navigating" || state.phase === "localizing")
      text += ` · target ${Math.min(state.target_index + 1, state.targets_total)} of ${state.targets_total}`;
    if (state.paused.length) text += " · paused";
    text += state.connected.includes(partner) ? ` · ${partner} here` : ` · waiting for the ${partner}`;
    // A trial on the rover starts only once it is connected, and pauses while it is away.
    const over = state.phase === "finished" || state.phase === "aborted";
    if (!over && (state.seats_needed || []).includes("robot") && !state.connected.includes("robot"))
      text += state.phase === "waiting" ? " · waiting for the robot" : " · robot not connected";
    $("status").textContent = text;
    $("status").dataset.phase = state.phase;
    document.body.dataset.phase = state.phase;
  }

  function handle(msg) {
    if (msg.type === "welcome") {
      state = msg; $("messages").innerHTML = "";
      msg.history.forEach((e) => { if (e.kind === "chat") addChat(e.payload); });
      lastSeq = msg.last_seq; renderStatus(); emit("welcome", msg); return;
    }
    if (msg.type === "error") { showError(msg.error); emit("error", msg); return; }
    if (msg.type === "replaced") { showError("This seat was opened in another window."); return; }
    if (msg.type !== "event") return;
    lastSeq = Math.max(lastSeq, msg.seq);
    const p = msg.payload;
    switch (msg.kind) {
      case "chat": addChat(p); break;
      case "phase": state.phase = p.phase; if (p.target_index !== null) state.target_index = p.target_index; break;
      case "connect": if (!state.connected.includes(p.role)) state.connected.push(p.role); break;
      case "disconnect": state.connected = state.connected.filter((r) => r !== p.role); break;
      case "paused": state.paused.push(p.reason); break;
      case "resumed": state.paused = state.paused.filter((r) => r !== p.reason); break;
    }
    renderStatus();
    emit(msg.kind, msg);
  }

  function connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    ws = new WebSocket(`${scheme}://${location.host}/ws/play?token=${encodeURIComponent(token)}`);
    ws.onopen = () => { delay = 500; showError(""); };
    ws.onmessage = (ev) => handle(JSON.parse(ev.data));
    ws.onclose = (ev) => {
      if (ev.code === 1008 || ev.code === 4409) { showError(`Disconnected: ${ev.reason || "refused"}`); return; }
      $("status").textContent = "reconnecting…";
      setTimeout(connect, delay); delay = Math.min(delay * 2, 8000);
    };
  }

  $("chat-form").addEventListener("submit", (ev) => {
    ev.preventDefault();
    const text = $("chat-input").value.trim();
    if (text && send("chat", {text})) $("chat-input").value = "";
  });
  setInterval(() => send("ping"), 20000);
  window.addEventListener("load", connect);
  return {on, send, token, role, get state() { return state; }, $};
})();
