// The Agent view: subscribes to the agent snapshot and draws the lifecycle, the trees (status per node),
// the last transitions with reasons and the mission progress. Text only through textContent.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const TOP = ["STARTUP", "IDLE", "EXEC", "MAPPING", "ERROR", "SHUTDOWN"];

  let subscribed = false;
  let lastAgent = 0;
  async function subscribe() {
    subscribed = true;
    const ack = await A.command("agent_view", { on: true });
    if (!ack.ok) subscribed = false;
  }
  A.socket.on("connect", subscribe);
  A.socket.on("disconnect", () => { subscribed = false; });
  A.socket.on("agent", (snap) => { lastAgent = Date.now(); draw(snap); });
  // Self-healing: no agent snapshot for 2 s while states arrive → subscribe again.
  A.onState(() => { if (!subscribed || (lastAgent && Date.now() - lastAgent > 2000)) { lastAgent = Date.now(); subscribe(); } });
  A.onState((s) => {
    const m = s.mission;
    $("agent-mission").textContent = m ? `${m.name}: ${m.state || ""}` : "no mission";
    $("agent-mission-progress").value = m && typeof m.progress === "number" ? m.progress : 0;
  });

  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }

  function machine(snap) {
    const box = $("machine");
    const states = (snap.machine && snap.machine.states) || TOP;
    const current = snap.state || "";
    box.innerHTML = "";
    for (const name of states) {
      const active = current === name || current.startsWith(name + ".");
      const s = el("span", `mstate${active ? " active" : ""}`, active && current !== name ? current : name);
      s.dataset.state = name;
      box.appendChild(s);
    }
  }

  function tree(node, ul) {
    const li = el("li", `node ${String(node.status || "INVALID").toLowerCase()}`);
    li.appendChild(el("span", "status", node.status || "—"));
    li.appendChild(el("span", "name", node.name));
    li.appendChild(el("small", "type", ` ${node.type || ""}`));
    const why = node.reason || node.feedback;
    if (why) li.appendChild(el("small", "why", ` — ${why}`));
    ul.appendChild(li);
    if (Array.isArray(node.children) && node.children.length) {
      const sub = el("ul");
      for (const c of node.children) tree(c, sub);
      li.appendChild(sub);
    }
  }

  function draw(snap) {
    if (!snap) return;
    if (snap.error && !snap.state) { $("agent-error").textContent = snap.error; return; }
    machine(snap);
    $("agent-current").textContent = snap.state || "—";
    $("agent-mode").textContent = snap.mode || "—";
    $("agent-task").textContent = snap.task || "—";
    $("agent-error").textContent = snap.error ? ` error: ${snap.error}` : "";
    $("agent-triggers").textContent = (snap.valid_triggers || []).join(", ") || "—";
    for (const [id, root] of [["agent-tree", snap.tree], ["agent-monitor", snap.monitor]]) {
      const ul = $(id);
      ul.innerHTML = "";
      if (root) tree(root, ul); else ul.appendChild(el("li", "hint", "—"));
    }
    const body = $("agent-transitions");
    body.innerHTML = "";
    for (const t of (snap.transitions || []).slice().reverse()) {
      const tr = el("tr", t.accepted === false ? "refused" : "");
      tr.appendChild(el("td", "", A.fmt(t.t, 1)));
      tr.appendChild(el("td", "", t.trigger || ""));
      tr.appendChild(el("td", "", `${t.source || "?"} → ${t.dest || "—"}`));
      tr.appendChild(el("td", "", t.reason || (t.accepted === false ? "refused" : "")));
      body.appendChild(tr);
    }
  }
})();
