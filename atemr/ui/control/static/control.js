// The Control page (the camera is camera.js): GO HERE (tap, drag for the heading, confirm; progress and arrival), SET
// POSITION and FIND POSITION, capture, record, missions, and the simulation panel (secondary-core screen and
// button, obstacle, kidnap).
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;

  const simTools = { obstacle: $("sim-obstacle"), kidnap: $("sim-kidnap") };
  for (const k of Object.keys(simTools)) if (!simTools[k]) delete simTools[k];

  // -- the map: pan and zoom, or a pose for GO HERE (then confirm) and SET POSITION -----------------------
  // A plain drag pans the map. GO HERE and SET POSITION each make the next tap a position (drag: the way the
  // robot faces); GO HERE then asks to confirm before the goal is sent, and switches to AUTO when needed.
  const goBtn = $("go-here"), setBtn = $("set-position"), hint = $("map-hint");
  const confirmBar = $("goal-confirm"), progress = $("goal-progress");
  let tool = null; // "go" | "set" | "obstacle" | "kidnap" | null
  let pending = null; // the goal waiting for CONFIRM
  const HINTS = {
    go: "Tap where the robot should go; drag from there to choose the way it faces.",
    set: "Tap where the robot is now; drag from there to show the way it faces.",
    obstacle: "Tap the map to drop an obstacle there.",
    kidnap: "Drag on the map to carry the robot there without telling it.",
  };
  function useTool(next) {
    tool = tool === next ? null : next;
    A.map.commandMode = tool !== null;
    goBtn.classList.toggle("on", tool === "go");
    setBtn.classList.toggle("on", tool === "set");
    hint.hidden = tool === null;
    hint.textContent = tool ? HINTS[tool] : "";
    for (const [n, b] of Object.entries(simTools)) b.classList.toggle("on", tool === n);
  }
  function askToConfirm(pose) {
    pending = pose;
    A.map.pending = pose;
    A.map.draw();
    $("goal-what").textContent = `Go to x ${pose.x_m.toFixed(2)} m, y ${pose.y_m.toFixed(2)} m?`;
    confirmBar.hidden = false;
  }
  function dropPending() {
    pending = null;
    A.map.pending = null;
    A.map.draw();
    confirmBar.hidden = true;
  }
  goBtn.addEventListener("click", () => { dropPending(); useTool("go"); });
  setBtn.addEventListener("click", () => { dropPending(); useTool("set"); });
  $("goal-cancel").addEventListener("click", dropPending);
  $("goal-go").addEventListener("click", async () => {
    if (!pending) return;
    const goal = pending;
    if (A.state.mode !== "AUTO") {
      const ack = await A.command("mode", { mode: "AUTO" }, "goal");
      if (!ack.ok) return;
      await A.until((s) => s.mode === "AUTO", 3000);
    }
    const ack = await A.command("goal", goal);
    if (ack.ok) { dropPending(); progress.textContent = "Going there…"; }
  });
  A.map.onPose = (pose) => {
    const used = tool;
    if (used === "obstacle") A.command("sim_obstacle", { x_m: pose.x_m, y_m: pose.y_m });
    else if (used === "kidnap") A.command("sim_kidnap", pose);
    else if (used === "set") A.command("initial_pose", pose);
    else if (used === "go") askToConfirm(pose);
    if (used === "go" || used === "set") useTool(null); // one tap each: the map pans again
  };
  A.onState((s) => {
    const n = s.navigation;
    if (s.agent_state === "EXEC" && s.goal && n) {
      const left = n.distance_left_m === null ? "—" : `${n.distance_left_m.toFixed(1)} m`;
      const eta = n.eta_s === null ? "" : `, about ${Math.max(1, Math.round(n.eta_s))} s`;
      progress.textContent = `On the way: ${left} left${eta}.`;
    } else if (s.agent_state !== "EXEC" && progress.textContent.startsWith("On the way")) {
      progress.textContent = ""; // a mission's last step, or a goal whose outcome came before this page
    }
  });
  A.onEvent((e) => {
    if (e.kind === "goal") progress.textContent = e.text === "Goal reached." ? "Arrived." : e.text;
    else if (e.kind === "mission") progress.textContent = e.text;
  });

  $("capture").addEventListener("click", () => A.command("capture_image"));
  const rec = $("record");
  // "Recording: done" said nothing: the acknowledgement says which way it went (the button then says the rest)
  A.STARTED.record_video = ({ on }) => (on ? "started" : "stopped, in Media");
  rec.addEventListener("click", () => A.command("record_video", { on: !A.state.recording }));
  $("localize-global").addEventListener("click", () => A.command("localize_globally"));
  A.onState((s) => {
    rec.classList.toggle("on", !!s.recording);
    rec.textContent = s.recording ? "STOP RECORDING" : "RECORD VIDEO";
  });

  // -- missions ------------------------------------------------------------------------------------
  const sel = $("mission-select");
  let known = "";
  A.onState((s) => {
    const names = (s.missions || []).join("\n");
    if (names !== known) {
      known = names;
      sel.innerHTML = "";
      for (const n of s.missions || []) { const o = document.createElement("option"); o.value = o.textContent = n; sel.appendChild(o); }
    }
    const m = s.mission;
    $("mission-progress").textContent = m ? `${m.name}: ${m.state || ""} ${m.progress !== undefined ? Math.round(100 * m.progress) + "%" : ""}` : "—";
  });
  $("mission-start").addEventListener("click", () => { if (sel.value) A.command("mission_start", { name: sel.value }); });
  $("mission-stop").addEventListener("click", () => A.command("mission_stop"));

  // -- simulation panel ----------------------------------------------------------------------------
  const panel = $("sim-panel");
  if (panel) {
    const screen = $("secondary-screen");
    // Not while the robot is silent (ATEMR.live false: alerts.js): each request then failed into the console.
    setInterval(() => {
      if (!document.hidden && A.live !== false) screen.src = `/api/secondary-screen.png?t=${Date.now()}`;
    }, 500);
    screen.onerror = () => { screen.alt = "no secondary-core screen"; };
    for (const b of panel.querySelectorAll("button[data-hold]")) {
      b.addEventListener("click", () => A.command("sim_button", { hold_s: parseFloat(b.dataset.hold) }));
    }
    for (const [name, btn] of Object.entries(simTools)) btn.addEventListener("click", () => useTool(name));
  }
})();
