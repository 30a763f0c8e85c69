// The Control page: camera on/off, map command modes (initial pose / goal, AUTO only), capture, record,
// cancel goal, missions, and the simulation panel (secondary-core screen and button, obstacle, kidnap).
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;

  // -- camera --------------------------------------------------------------------------------------
  // CAM-ON shows the MJPEG stream (/api/camera.mjpeg: binary JPEG parts the browser decodes itself, read by
  // the server only while this page watches). When the stream cannot be had (it fails to load), the page
  // falls back to JPEG frames over the Socket.IO connection (the "camera" subscription).
  const cam = $("camera"), camOff = $("camera-off"), camBtn = $("cam-toggle");
  const MJPEG = "/api/camera.mjpeg";
  let transport = "mjpeg"; // "mjpeg" | "socket"
  let camOn = false;
  let camWanted = true; // CAM-ON by default (thesis 3.5.3); off saves bandwidth
  let camPending = false;
  function showCamera(on) {
    camOn = on;
    camBtn.textContent = on ? "CAM-ON" : "CAM-OFF";
    camBtn.classList.toggle("on", on);
    cam.hidden = !on; camOff.hidden = on;
    cam.dataset.transport = transport;
  }
  async function setCamera(on) {
    if (transport === "mjpeg") {
      if (on) cam.src = `${MJPEG}?t=${Date.now()}`; // a new stream (also after a reconnect)
      else cam.removeAttribute("src"); // the browser drops the stream: the server stops reading frames
      showCamera(on);
      return;
    }
    camPending = true;
    const ack = await A.command("camera", { on });
    camPending = false;
    if (ack.ok) showCamera(on);
  }
  cam.addEventListener("error", () => {
    if (transport !== "mjpeg" || !cam.getAttribute("src")) return;
    transport = "socket";
    cam.removeAttribute("src");
    showCamera(false);
    setCamera(camWanted);
  });
  camBtn.addEventListener("click", () => { camWanted = !camOn; setCamera(camWanted); });
  A.socket.on("camera", (f) => {
    if (transport === "socket" && camOn && f && f.jpeg) cam.src = `data:image/jpeg;base64,${f.jpeg}`;
  });
  A.socket.on("connect", () => setCamera(camWanted));
  // Self-healing: a subscription lost on the way (reconnect, a refused ack) is asked for again.
  A.onState(() => {
    if (transport === "socket" && camWanted !== camOn && !camPending && A.socket.status === "ONLINE") setCamera(camWanted);
  });

  // -- map modes: MAP CTL (pan/zoom) / SEND CMD, and INITIAL POS. / SEND GOAL ---------------------------
  const ctlBtn = $("map-ctl"), cmdBtn = $("map-cmd");
  let sendGoal = false;
  let simTool = null; // "obstacle" | "kidnap" | null
  function applyModes() {
    A.map.commandMode = ctlBtn.textContent === "SEND CMD" || simTool !== null;
  }
  ctlBtn.addEventListener("click", () => {
    const toCmd = ctlBtn.textContent === "MAP CTL";
    ctlBtn.textContent = toCmd ? "SEND CMD" : "MAP CTL";
    ctlBtn.classList.toggle("on", !toCmd);
    applyModes();
  });
  cmdBtn.addEventListener("click", () => {
    if (!sendGoal && A.state.mode !== "AUTO") {
      A.report("send goal", { ok: false, reason: "switch to AUTO first" });
      return;
    }
    sendGoal = !sendGoal;
    cmdBtn.textContent = sendGoal ? "SEND GOAL" : "INITIAL POS.";
    cmdBtn.classList.toggle("on", !sendGoal);
  });
  A.onState((s) => {
    if (sendGoal && s.mode !== "AUTO") { sendGoal = false; cmdBtn.textContent = "INITIAL POS."; cmdBtn.classList.add("on"); }
  });
  A.map.onPose = (pose) => {
    if (simTool === "obstacle") A.command("sim_obstacle", { x_m: pose.x_m, y_m: pose.y_m });
    else if (simTool === "kidnap") A.command("sim_kidnap", pose);
    else if (sendGoal) A.command("goal", pose);
    else A.command("initial_pose", pose);
  };

  $("capture").addEventListener("click", () => A.command("capture_image"));
  const rec = $("record");
  rec.addEventListener("click", () => A.command("record_video", { on: !A.state.recording }));
  $("cancel-goal").addEventListener("click", () => A.command("cancel_goal"));
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
    setInterval(() => { if (!document.hidden) screen.src = `/api/secondary-screen.png?t=${Date.now()}`; }, 500);
    screen.onerror = () => { screen.alt = "no secondary-core screen"; };
    for (const b of panel.querySelectorAll("button[data-hold]")) {
      b.addEventListener("click", () => A.command("sim_button", { hold_s: parseFloat(b.dataset.hold) }));
    }
    const tools = { obstacle: $("sim-obstacle"), kidnap: $("sim-kidnap") };
    for (const [name, btn] of Object.entries(tools)) {
      btn.addEventListener("click", () => {
        simTool = simTool === name ? null : name;
        for (const [n, b] of Object.entries(tools)) b.classList.toggle("on", simTool === n);
        applyModes();
      });
    }
  }
})();
