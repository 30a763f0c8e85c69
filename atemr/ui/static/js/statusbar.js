// The status bar on every page (socket ONLINE/OFFLINE/ERROR, agent state, emergency) and the page-wide
// ATEMR object: the socket, the latest state, listeners, and `command(event, data)` with feedback.
"use strict";

(function () {
  const listeners = [];
  const ATEMR = {
    state: {},
    socket: null,
    onState(f) { listeners.push(f); if (Object.keys(this.state).length) f(this.state); },
    csrf: (document.querySelector('meta[name="csrf-token"]') || {}).content || "",
    async command(event, data) {
      if (!this.socket) return { ok: false, reason: "no connection on this page" };
      const ack = await this.socket.emit(event, data);
      if (event !== "joystick") this.report(event, ack);
      return ack;
    },
    report(what, ack) {
      const out = document.getElementById("command-result");
      if (!out) return;
      out.textContent = ack.ok ? `${what}: ok` : `${what}: refused — ${ack.reason}`;
      out.className = ack.ok ? "hint ok" : "hint error";
    },
    fmt(v, digits = 2) { return typeof v === "number" && isFinite(v) ? v.toFixed(digits) : "—"; },
  };
  window.ATEMR = ATEMR;

  // Forms that destroy something ask first (no inline handlers: the CSP forbids them).
  document.addEventListener("submit", (e) => {
    const question = e.target.dataset && e.target.dataset.confirm;
    if (question && !window.confirm(question)) e.preventDefault();
  }, true);

  const sock = document.getElementById("sock");
  const agent = document.getElementById("agent-state");
  const emergency = document.getElementById("emergency");

  function showStatus(status) {
    sock.textContent = `WS:${status}`;
    sock.className = `ind ${status.toLowerCase()}`;
  }

  function showState(s) {
    agent.textContent = s.agent_state || "—";
    agent.dataset.state = s.agent_state || "";
    if (s.emergency === true) { emergency.textContent = "EMERGENCY"; emergency.className = "ind error"; }
    else if (s.emergency === false) { emergency.textContent = "NO EMERGENCY"; emergency.className = "ind online"; }
  }

  if (document.body.dataset.socket === "on") {
    ATEMR.socket = new AtemrSocket(showStatus);
    ATEMR.socket.on("state", (s) => {
      ATEMR.state = s || {};
      showState(ATEMR.state);
      for (const f of listeners) {
        try { f(ATEMR.state); } catch (err) { console.error(err); }
      }
    });
    fetch("/api/state", { headers: { Accept: "application/json" } })
      .then((r) => (r.ok ? r.json() : null))
      .then((s) => { if (s && !Object.keys(ATEMR.state).length) { ATEMR.state = s; showState(s); listeners.forEach((f) => f(s)); } })
      .catch(() => {});
  }
})();
