// The Agent view: live (the `agent` snapshot over Socket.IO) or replaying a recorded trace (frames from
// /api/traces/<name>/frame?t=). Both draw the same: the lifecycle, the trees (status and ticks per node,
// search, collapse), the blackboard (value, writer, time), the last transitions; in replay the map shows
// where the robot was. Text only through textContent.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const TOP = ["STARTUP", "IDLE", "EXEC", "MAPPING", "ERROR", "SHUTDOWN"];

  // -- view state ---------------------------------------------------------------------------------
  const collapsed = new Set();   // node keys ("tree:root/0/2") whose children are hidden
  let lastSnap = null;           // what is drawn (a live snapshot or a replay frame)
  let query = "";
  const replay = { name: null, summary: null, t: 0, playing: false, timer: null, busy: false, pending: null };
  A.agentView = { replay, collapsed };

  // -- live ---------------------------------------------------------------------------------------
  let subscribed = false;
  let lastAgent = 0;
  async function subscribe() {
    if (A.socket.status !== "ONLINE") return; // a state from before the connection: "connect" subscribes
    subscribed = true;
    const ack = await A.command("agent_view", { on: true });
    if (!ack.ok) subscribed = false;
  }
  A.socket.on("connect", subscribe);
  A.socket.on("disconnect", () => { subscribed = false; });
  A.socket.on("agent", (snap) => { lastAgent = Date.now(); if (!replay.name) draw(snap); });
  // Self-healing: no agent snapshot for 2 s while states arrive → subscribe again.
  A.onState(() => { if (!subscribed || (lastAgent && Date.now() - lastAgent > 2000)) { lastAgent = Date.now(); subscribe(); } });
  A.onState((s) => {
    if (replay.name) return;  // the replay draws its own task and pose
    const m = s.mission;
    $("agent-mission").textContent = m ? `${m.name}: ${m.state || ""}` : s.goal ? "a single goal (no mission)"
      : "no mission";
    $("agent-mission-progress").value = m && typeof m.progress === "number" ? m.progress : 0;
    if (A.map) A.map.update(s);
  });

  // -- drawing ------------------------------------------------------------------------------------
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
      // a parent (IDLE) names the leaf it is in only when the leaf has no chip of its own (IDLE.MANUAL twice read odd)
      const label = active && current !== name && !states.includes(current) ? current : name;
      const s = el("span", `mstate${active ? " active" : ""}`, label);
      s.dataset.state = name;
      box.appendChild(s);
    }
  }

  function text(node) {
    return `${node.name} ${node.type || ""} ${node.status || ""} ${node.reason || node.feedback || ""}`.toLowerCase();
  }

  // Which nodes to show under a search: the matches and their ancestors (null: no search, show all).
  function matches(node, key, out) {
    let any = query !== "" && text(node).includes(query);
    if (any) out.hit.add(key);
    (node.children || []).forEach((c, i) => { if (matches(c, `${key}/${i}`, out)) any = true; });
    if (any) out.shown.add(key);
    return any;
  }

  function tree(node, ul, key, search) {
    if (search && !search.shown.has(key)) return;
    const kids = Array.isArray(node.children) ? node.children : [];
    const closed = !search && collapsed.has(key);
    const li = el("li", `node ${String(node.status || "INVALID").toLowerCase()}${closed ? " collapsed" : ""}` +
                        `${search && search.hit.has(key) ? " match" : ""}`);
    li.dataset.key = key;
    const toggle = el("span", "toggle", kids.length ? (closed ? "▸" : "▾") : "");
    if (kids.length) {
      toggle.setAttribute("role", "button");
      toggle.title = closed ? "expand" : "collapse";
      toggle.addEventListener("click", () => {
        if (collapsed.has(key)) collapsed.delete(key); else collapsed.add(key);
        redraw();
      });
    }
    li.appendChild(toggle);
    li.appendChild(el("span", "status", node.status || "—"));
    li.appendChild(el("span", "name", node.name));
    li.appendChild(el("small", "type", ` ${node.type || ""}`));
    if (typeof node.ticks === "number") li.appendChild(el("small", "ticks", ` ×${node.ticks}`));
    const why = node.reason || node.feedback;
    if (why) li.appendChild(el("small", "why", ` — ${why}`));
    if (closed && kids.length) li.appendChild(el("small", "hint", ` (${kids.length} hidden)`));
    ul.appendChild(li);
    if (kids.length) {
      const sub = el("ul");
      kids.forEach((c, i) => tree(c, sub, `${key}/${i}`, search));
      li.appendChild(sub);
    }
  }

  function keysOf(node, key, out) {
    if (Array.isArray(node.children) && node.children.length) {
      out.push(key);
      node.children.forEach((c, i) => keysOf(c, `${key}/${i}`, out));
    }
    return out;
  }

  function trees(snap) {
    for (const [id, slot, root] of [["agent-tree", "tree", snap.tree], ["agent-monitor", "monitor", snap.monitor]]) {
      const ul = $(id);
      ul.innerHTML = "";
      if (!root) { ul.appendChild(el("li", "hint", "—")); continue; }
      const key = `${slot}:${root.name}`;
      let search = null;
      if (query) {
        search = { shown: new Set(), hit: new Set() };
        if (!matches(root, key, search)) { ul.appendChild(el("li", "hint", `no node matches “${query}”`)); continue; }
      }
      tree(root, ul, key, search);
    }
  }

  function blackboard(snap) {
    const body = $("agent-blackboard");
    body.innerHTML = "";
    const entries = Object.entries(snap.blackboard || {});
    let shown = 0;
    for (const [key, entry] of entries) {
      const e = entry && typeof entry === "object" && "value" in entry ? entry : { value: entry, by: "", t: null };
      const value = JSON.stringify(e.value);
      if (query && !`${key} ${value} ${e.by || ""}`.toLowerCase().includes(query)) continue;
      shown += 1;
      const tr = el("tr");
      tr.dataset.key = key;
      tr.appendChild(el("td", "key", key));
      tr.appendChild(el("td", "value", value === undefined ? "—" : value));
      tr.appendChild(el("td", "by", e.by || "—"));
      tr.appendChild(el("td", "t", typeof e.t === "number" ? A.fmt(e.t, 1) : "—"));
      body.appendChild(tr);
    }
    $("agent-bb-count").textContent = query ? `(${shown} of ${entries.length} keys)` : `(${entries.length} keys)`;
  }

  function transitions(snap) {
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

  function draw(snap) {
    if (!snap) return;
    lastSnap = snap;
    if (snap.error && !snap.state) { $("agent-error").textContent = snap.error; return; }
    machine(snap);
    $("agent-current").textContent = snap.state || "—";
    $("agent-mode").textContent = snap.mode || "—";
    $("agent-task").textContent = snap.task || "—";
    $("agent-error").textContent = snap.error ? ` error: ${snap.error}` : "";
    $("agent-triggers").textContent = replay.name ? "(replay)" : (snap.valid_triggers || []).join(", ") || "—";
    trees(snap);
    blackboard(snap);
    transitions(snap);
  }

  function redraw() { if (lastSnap) draw(lastSnap); }

  // -- search and collapse ------------------------------------------------------------------------
  $("agent-search").addEventListener("input", (e) => { query = e.target.value.trim().toLowerCase(); redraw(); });
  $("tree-collapse").addEventListener("click", () => {
    if (!lastSnap) return;
    for (const [slot, root] of [["tree", lastSnap.tree], ["monitor", lastSnap.monitor]]) {
      if (root) keysOf(root, `${slot}:${root.name}`, []).forEach((k) => collapsed.add(k));
    }
    redraw();
  });
  $("tree-expand").addEventListener("click", () => { collapsed.clear(); redraw(); });

  // -- map ----------------------------------------------------------------------------------------
  const canvas = $("map");
  if (canvas) {
    A.map = new MapView(canvas);
    const reset = $("map-reset");
    if (reset) reset.addEventListener("click", () => A.map.reset());
  }

  // -- replay -------------------------------------------------------------------------------------
  async function getJson(url) {
    const r = await fetch(url, { headers: { Accept: "application/json" } });
    const body = await r.json().catch(() => ({ ok: false, reason: `HTTP ${r.status}` }));
    if (!r.ok) throw new Error(body.reason || `HTTP ${r.status}`);
    return body;
  }

  async function listTraces(select) {
    try {
      const got = await getJson("/api/traces");
      const box = $("trace-select");
      box.innerHTML = "";
      for (const f of got.traces) {
        const o = el("option", "", `${f.name} (${Math.ceil(f.size_bytes / 1024)} kB)`);
        o.value = f.name;
        box.appendChild(o);
      }
      if (!got.traces.length) box.appendChild(el("option", "", "no recorded traces"));
      if (select) box.value = select;
    } catch (err) {
      $("replay-warning").textContent = `traces: ${err.message}`;
    }
  }

  function controls(on) {
    for (const id of ["replay-back", "replay-play", "replay-step", "replay-seek", "replay-live"]) $(id).disabled = !on;
    $("agent-source").textContent = on ? `REPLAY ${replay.name}` : "LIVE";
    $("agent-source").className = `source ${on ? "replay" : "live"}`;
  }

  async function openTrace(name) {
    stop();
    $("replay-warning").textContent = "";
    try {
      const summary = await getJson(`/api/traces/${encodeURIComponent(name)}`);
      replay.name = name;
      replay.summary = summary;
      const seek = $("replay-seek");
      seek.min = summary.start_t; seek.max = summary.end_t; seek.value = summary.start_t;
      $("replay-end").textContent = A.fmt(summary.end_t, 1);
      const meta = summary.meta || {};
      $("replay-info").textContent = `· ${summary.records} records${meta.map ? ` · map ${meta.map}` : ""}` +
        `${meta.map && A.state.active_map && meta.map !== A.state.active_map ? ` (drawn on ${A.state.active_map})` : ""}`;
      $("replay-warning").textContent = (summary.warnings || []).join(" ");
      controls(true);
      await seekTo(summary.start_t);
    } catch (err) {
      $("replay-warning").textContent = `cannot open ${name}: ${err.message}`;
    }
  }

  // Frames are fetched one at a time; a seek while one is in flight replaces the pending one.
  async function seekTo(t) {
    if (!replay.name) return;
    if (replay.busy) { replay.pending = t; return; }
    replay.busy = true;
    try {
      const frame = await getJson(`/api/traces/${encodeURIComponent(replay.name)}/frame?t=${encodeURIComponent(t)}`);
      if (!replay.name) return;
      replay.t = frame.t;
      replay.frame = frame;
      $("replay-time").textContent = A.fmt(frame.t, 1);
      if (document.activeElement !== $("replay-seek") || !replay.playing) $("replay-seek").value = frame.t;
      draw(frame);
      $("agent-mission").textContent = frame.task ? `${frame.task} (recorded)` : "no task (recorded)";
      $("agent-mission-progress").value = 0;
      if (A.map) A.map.update({ pose: frame.pose, map_version: A.state.map_version });
      if (replay.playing && frame.t >= replay.summary.end_t) stop();
    } catch (err) {
      $("replay-warning").textContent = err.message;
    } finally {
      replay.busy = false;
      if (replay.pending !== null) { const next = replay.pending; replay.pending = null; seekTo(next); }
    }
  }

  function stop() {
    replay.playing = false;
    if (replay.timer) clearInterval(replay.timer);
    replay.timer = null;
    $("replay-play").textContent = "PLAY";
  }

  function play() {
    if (!replay.name) return;
    if (replay.t >= replay.summary.end_t) replay.t = replay.summary.start_t;
    replay.playing = true;
    $("replay-play").textContent = "PAUSE";
    const tickMs = 100;
    replay.timer = setInterval(() => {
      if (replay.busy) return;
      const speed = Number($("replay-speed").value) || 1;
      seekTo(Math.min(replay.summary.end_t, replay.t + speed * tickMs / 1000));
    }, tickMs);
  }

  function live() {
    stop();
    replay.name = null; replay.summary = null; replay.frame = null;
    controls(false);
    $("replay-time").textContent = "—"; $("replay-end").textContent = "—"; $("replay-info").textContent = "";
    if (A.map) A.map.update(A.state);
  }

  $("trace-open").addEventListener("click", () => { const n = $("trace-select").value; if (n) openTrace(n); });
  $("trace-select").addEventListener("focus", () => listTraces($("trace-select").value));  // new parts, uploads
  $("replay-live").addEventListener("click", live);
  $("replay-play").addEventListener("click", () => (replay.playing ? stop() : play()));
  $("replay-step").addEventListener("click", () => {
    stop();
    if (replay.frame && replay.frame.next_t !== null) seekTo(replay.frame.next_t);
  });
  $("replay-back").addEventListener("click", () => {
    stop();
    if (replay.frame && replay.frame.prev_t !== null) seekTo(replay.frame.prev_t);
  });
  $("replay-seek").addEventListener("input", (e) => { stop(); seekTo(Number(e.target.value)); });
  $("trace-upload-form").addEventListener("submit", async (e) => {
    e.preventDefault();
    const file = $("trace-file").files[0];
    if (!file) { $("replay-warning").textContent = "choose a .mcap recording first"; return; }
    const form = new FormData();
    form.append("file", file);
    const r = await fetch("/api/traces", { method: "POST", body: form, headers: { "X-CSRF-Token": A.csrf } });
    const body = await r.json().catch(() => ({ ok: false, reason: `HTTP ${r.status}` }));
    A.report("upload", body);
    if (!body.ok) { $("replay-warning").textContent = `upload refused: ${body.reason}`; return; }
    await listTraces(body.name);
    await openTrace(body.name);
  });

  listTraces();
})();
