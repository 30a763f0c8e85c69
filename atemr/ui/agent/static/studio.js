// The Agent page's studio panel: the robot's autonomy level (set it, see which transitions it gates) and
// hot reload (the explicit reload action, the latest result with its error position, and the diff).
// Text only through textContent.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const rank = { off: 0, low: 1, high: 2, full: 3 };
  let chosen = false; // the operator touched the select: do not overwrite it with pushes

  $("autonomy-select").addEventListener("change", () => { chosen = true; });
  $("autonomy-set").addEventListener("click", async () => {
    const ack = await A.command("autonomy_level", { level: $("autonomy-select").value });
    if (ack.ok) chosen = false;
  });
  $("agent-reload").addEventListener("click", () => A.command("agent_reload"));

  A.onState((s) => {
    if (s.autonomy && !chosen) $("autonomy-select").value = s.autonomy.level;
  });

  function gated(snap) {
    const level = snap.autonomy && snap.autonomy.level;
    const out = ((snap.machine && snap.machine.transitions) || [])
      .filter((t) => t.autonomy && level && rank[t.autonomy] > rank[level])
      .map((t) => `${t.trigger} → ${t.dest} (${t.autonomy})`);
    $("autonomy-gated").textContent = out.length ? out.join(", ") : "nothing: every transition is taken on its own";
  }

  function reload(snap) {
    const r = (snap.reloads || [])[(snap.reloads || []).length - 1];
    if (!r) return;
    const name = String(r.file || "").split("/").pop();
    const status = $("reload-status");
    status.textContent = `${r.kind} ${name}: ${r.status} — ${r.reason}`;
    status.dataset.status = r.status;
    status.className = r.status === "invalid" || r.status === "refused" ? "hint error" : "hint ok";
    const e = r.error;
    $("reload-error").textContent = e ? `line ${e.line ?? "?"}, column ${e.column ?? "?"}: ${e.message}` : "";
    const pre = $("reload-diff");
    pre.innerHTML = "";
    pre.hidden = !r.diff;
    for (const line of String(r.diff || "").split("\n")) {
      const cls = line.startsWith("+") && !line.startsWith("+++") ? "add"
        : line.startsWith("-") && !line.startsWith("---") ? "del" : "";
      const span = document.createElement("span");
      if (cls) span.className = cls;
      span.textContent = `${line}\n`;
      pre.appendChild(span);
    }
  }

  A.socket.on("agent", (snap) => {
    if (!snap || (snap.error && !snap.state)) return;
    gated(snap);
    reload(snap);
  });
})();
