// The Status and Control panel shared by Control and Mapping: MANUAL/AUTO, agent state and map, level-1
// and level-2 states, wheel speeds, emergency, the joystick (pointer = mouse and touch, arrow keys/WASD,
// a gamepad when the browser has one) and the 1 Hz CPU/memory/disk graph. Also creates the map view.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;

  // -- map ----------------------------------------------------------------------------------------
  const canvas = $("map");
  if (canvas) {
    A.map = new MapView(canvas);
    A.onState((s) => A.map.update(s));
    const reset = $("map-reset");
    if (reset) reset.addEventListener("click", () => A.map.reset());
  }

  // -- mode, states, wheels --------------------------------------------------------------------------
  const modeBtn = $("mode-toggle");
  modeBtn.addEventListener("click", async () => {
    const want = A.state.mode === "AUTO" ? "MANUAL" : "AUTO";
    await A.command("mode", { mode: want });
  });

  // The level-1 and level-2 bits of CAN 0x153 (`RobotState.level1`, `level2`): what each one watches, on hover.
  const LED_WORDS = {
    heartbeat: "the robot's two computers hear each other (CAN heartbeat 0x157)",
    hardware: "every part below (Level 2) answers",
    connectivity: "the robot has a network address you can reach it on",
    localization: "the robot knows where it is on the map",
    left_motor: "the left wheel's motor answers", right_motor: "the right wheel's motor answers",
    imu: "the motion sensor (IMU) reports", lidar: "the laser scanner reports", camera: "the camera sends frames",
    webserver: "this dashboard's server runs",
    ir_front: "the front floor sensors (stairs) report", ir_rear: "the rear floor sensors (stairs) report",
  };
  function leds(el, states) {
    if (!el) return;
    const entries = Object.entries(states || {});
    el.innerHTML = "";
    for (const [name, ok] of entries) {
      const span = document.createElement("span");
      span.className = `led ${ok ? "ok" : "bad"}`;
      span.textContent = name.replace(/_/g, " ").toUpperCase();
      span.title = `${LED_WORDS[name] || name}: ${ok ? "yes" : "NO"}`;
      if (name === "auto") {
        span.className = "led mode"; span.textContent = `MODE ${ok ? "AUTO" : "MANUAL"}`;
        span.title = ok ? "AUTO: the robot drives itself to goals and on missions" : "MANUAL: you drive it with the joystick";
      }
      span.dataset.name = name;
      el.appendChild(span);
    }
    if (!entries.length) el.textContent = "—";
  }

  // -- localization: the one confidence number, the same the robot decides by ---------------------------
  function localization(loc) {
    const led = $("localization");
    if (!led || !loc) return;
    const pct = (v) => `${Math.round(100 * v)}%`;
    led.className = `led ${loc.localized ? "ok" : "bad"}`;
    led.textContent = loc.localized ? `LOCALIZED ${pct(loc.confidence)}` : `NOT LOCALIZED ${pct(loc.confidence)}`;
    const detail = $("localization-detail");
    const places = (loc.candidates || []).length;
    detail.textContent = loc.localized ? `limit ${pct(loc.limit)}`
      : `${LOCALIZATION_WORDS[loc.state] || loc.state}` +
        `${places ? `: ${places} places look alike (drawn on the map); ` +
          (loc.looking_around ? "turning in place to tell them apart" : "drive a little to tell them apart") : ""}; ` +
        `needs ${pct(loc.limit)} — SET POSITION or FIND POSITION`;
    detail.title = `localization state: ${loc.state}`; // the engineer's name, on hover
  }
  // Localization's states (`atemr.domain.status.LocalizationState`) as a carer reads them.
  const LOCALIZATION_WORDS = {
    uninitialized: "position not known yet", lost: "lost its position", "pose set": "checking the position set",
    searching: "searching for its position", ambiguous: "unsure between places", failed: "could not find its position",
    "no map": "no map chosen",
  };

  $("level2-toggle").addEventListener("click", () => { $("level2").hidden = !$("level2").hidden; });
  $("graph-toggle").addEventListener("click", () => { $("sysgraph").hidden = !$("sysgraph").hidden; graph.draw(); });


  // -- the latest events, newest first -------------------------------------------------------------
  // When it happened, on this device's clock: the time of day, with the date once it is not today's.
  function clock(unixS) {
    if (typeof unixS !== "number") return "—";
    const at = new Date(unixS * 1000);
    const time = at.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit" });
    return at.toDateString() === new Date().toDateString() ? time
      : `${at.toLocaleDateString([], { day: "numeric", month: "short" })} ${time}`;
  }
  let lastEvents = "";
  function events(list) {
    const el = $("events");
    if (!el || !Array.isArray(list)) return;
    const key = JSON.stringify(list.slice(-8));
    if (key === lastEvents) return;
    lastEvents = key;
    el.innerHTML = "";
    for (const e of list.slice(-8).reverse()) {
      const li = document.createElement("li");
      li.className = `event ${e.kind || ""}`;
      // In the alert's words where it has some ("The robot knows where it is."); the technical text on hover.
      const said = A.plainEvent ? A.plainEvent(e) : null;
      li.textContent = `${clock(e.unix_s)}  ${said ? said[0] : `${e.kind || ""}: ${e.text || ""}`}`;
      li.title = `${e.kind || ""}: ${e.text || ""} (robot time ${A.fmt(e.t, 1)} s)`;
      el.appendChild(li);
    }
  }

  // -- joystick ------------------------------------------------------------------------------------
  const pad = $("joystick");
  const knob = pad.querySelector(".knob");
  const readout = $("joy-readout");
  const joy = { x: 0, y: 0, pointer: false, keys: new Set(), gamepad: false, timer: null };
  const KEYS = { ArrowUp: "f", w: "f", W: "f", ArrowDown: "b", s: "b", S: "b", ArrowLeft: "l", a: "l", A: "l",
                 ArrowRight: "r", d: "r", D: "r" };

  function limits() {
    const l = A.state.limits || {};
    return [l.linear_mps > 0 ? l.linear_mps : 0.5, l.angular_radps > 0 ? l.angular_radps : 1.0];
  }

  function current() {
    let x = joy.x, y = joy.y;
    if (!joy.pointer && !joy.gamepad) {
      y = (joy.keys.has("f") ? 1 : 0) - (joy.keys.has("b") ? 1 : 0);
      x = (joy.keys.has("r") ? 1 : 0) - (joy.keys.has("l") ? 1 : 0);
    }
    const [lin, ang] = limits();
    return { linear_mps: +(y * lin).toFixed(3), angular_radps: +(-x * ang).toFixed(3), x, y };
  }

  function show(c) {
    const r = pad.clientWidth / 2 - knob.clientWidth / 2;
    knob.style.transform = `translate(${c.x * r}px, ${-c.y * r}px)`;
    readout.textContent = `${c.linear_mps.toFixed(2)} m/s · ${c.angular_radps.toFixed(2)} rad/s`;
  }

  function held() { return joy.pointer || joy.keys.size > 0 || joy.gamepad; }

  function send() {
    const c = current();
    show(c);
    // No state from the robot: driving blind is off (a stop still goes out) until the state is back.
    if (!A.live && (c.linear_mps !== 0 || c.angular_radps !== 0)) return;
    A.command("joystick", { linear_mps: c.linear_mps, angular_radps: c.angular_radps });
  }
  function stopResending() { if (joy.timer) { clearInterval(joy.timer); joy.timer = null; } }

  // While held, resend every 100 ms: the robot drops joystick input older than 0.5 s.
  function update() {
    if (held() && !joy.timer) { send(); joy.timer = setInterval(send, 100); }
    else if (!held() && joy.timer) { clearInterval(joy.timer); joy.timer = null; joy.x = joy.y = 0; send(); }
    else show(current());
  }

  function fromPointer(e) {
    const r = pad.getBoundingClientRect();
    let x = (e.clientX - r.left - r.width / 2) / (r.width / 2);
    let y = -(e.clientY - r.top - r.height / 2) / (r.height / 2);
    const n = Math.hypot(x, y);
    if (n > 1) { x /= n; y /= n; }
    joy.x = x; joy.y = y;
  }

  pad.style.touchAction = "none";
  pad.addEventListener("pointerdown", (e) => {
    if (!A.live) return; // no state from the robot: driving blind is off
    pad.setPointerCapture(e.pointerId); joy.pointer = true; fromPointer(e); update();
  });
  pad.addEventListener("pointermove", (e) => { if (joy.pointer) { fromPointer(e); show(current()); } });
  const release = () => { joy.pointer = false; joy.x = joy.y = 0; update(); };
  pad.addEventListener("pointerup", release);
  pad.addEventListener("pointercancel", release);

  const typing = (e) => /^(INPUT|TEXTAREA|SELECT)$/.test(e.target.tagName);
  document.addEventListener("keydown", (e) => {
    const k = KEYS[e.key];
    if (!k || typing(e) || e.ctrlKey || e.metaKey || e.altKey) return;
    e.preventDefault();
    if (!joy.keys.has(k)) { joy.keys.add(k); update(); }
  });
  document.addEventListener("keyup", (e) => {
    const k = KEYS[e.key];
    if (k && joy.keys.delete(k)) update();
  });
  window.addEventListener("blur", () => { joy.keys.clear(); joy.pointer = false; update(); });

  function pollGamepad() {
    const pads = navigator.getGamepads ? [...navigator.getGamepads()].filter(Boolean) : [];
    if (pads.length) {
      const g = pads[0];
      const dz = (v) => (Math.abs(v) < 0.12 ? 0 : v);
      const x = dz(g.axes[0] || 0), y = -dz(g.axes[1] || 0);
      const active = x !== 0 || y !== 0;
      if (active) { joy.x = x; joy.y = y; }
      if (active !== joy.gamepad) { joy.gamepad = active; update(); }
      requestAnimationFrame(pollGamepad);
    }
  }
  window.addEventListener("gamepadconnected", () => requestAnimationFrame(pollGamepad));

  // -- STOP: the joystick released and any goal or mission cancelled, at once ---------------------------
  const stopBtn = $("stop");
  stopBtn.addEventListener("click", async () => {
    joy.pointer = false; joy.keys.clear(); joy.x = joy.y = 0; stopResending();
    show(current());
    if (A.state.agent_state === "EXEC") await A.command("cancel_goal");
    else {
      // also ends FIND POSITION's look around: its "turning in place" gives way (the joystick's ack says nothing)
      const ack = await A.command("joystick", { linear_mps: 0, angular_radps: 0 });
      if (ack.ok) A.report("cancel_goal", ack);
    }
    A.alert("Stopped.", "ok");
  });
  const note = $("drive-note");
  function driveNote(s) {
    note.textContent = s.mode === "AUTO"
      ? "AUTO: the robot drives itself; the joystick is off. Switch to MANUAL to drive."
      : "";
    pad.classList.toggle("off", s.mode === "AUTO");
  }

  // -- 1 Hz CPU / memory / disk graph ----------------------------------------------------------------
  const graph = {
    canvas: $("sysgraph"),
    samples: [],
    lastT: null,
    add(sample) {
      if (!sample || sample.t === this.lastT) return;
      this.lastT = sample.t;
      this.samples.push(sample);
      if (this.samples.length > 120) this.samples.shift();
      this.draw();
    },
    draw() {
      const c = this.canvas;
      if (!c || c.hidden) return;
      // Crisp at any device pixel ratio: the backing store follows the displayed size times the ratio.
      const ratio = window.devicePixelRatio || 1;
      const w = c.clientWidth || 320, h = c.clientHeight || 120;
      if (c.width !== Math.round(w * ratio) || c.height !== Math.round(h * ratio)) {
        c.width = Math.round(w * ratio); c.height = Math.round(h * ratio);
      }
      const ctx = c.getContext("2d");
      ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
      ctx.clearRect(0, 0, w, h);
      const left = 34, right = 6, top = 18, bottom = 18; // room for the axes' labels
      const pw = w - left - right, ph = h - top - bottom;
      const y = (p) => top + ph * (1 - p / 100);
      ctx.font = "10px sans-serif"; ctx.fillStyle = "#656d76"; ctx.textAlign = "right"; ctx.textBaseline = "middle";
      ctx.strokeStyle = "#d0d7de"; ctx.lineWidth = 1;
      for (const p of [0, 25, 50, 75, 100]) {
        ctx.beginPath(); ctx.moveTo(left, y(p)); ctx.lineTo(left + pw, y(p)); ctx.stroke();
        ctx.fillText(`${p}%`, left - 4, y(p));
      }
      ctx.textAlign = "center"; ctx.textBaseline = "top";
      for (const ago of [120, 90, 60, 30, 0]) {
        const x = left + pw * (1 - ago / 119);
        ctx.fillText(ago ? `-${ago} s` : "now", Math.min(Math.max(x, left + 10), left + pw - 10), top + ph + 4);
      }
      const series = [["cpu_percent", "#cf222e", "CPU"], ["memory_percent", "#1f6feb", "MEM"], ["disk_percent", "#2da44e", "DISK"]];
      const n = this.samples.length;
      ctx.textAlign = "left"; ctx.textBaseline = "alphabetic";
      series.forEach(([key, color, label], i) => {
        ctx.strokeStyle = color; ctx.lineWidth = 2; ctx.beginPath();
        this.samples.forEach((s, j) => {
          const x = left + pw - (n - 1 - j) * (pw / 119);
          if (j) ctx.lineTo(x, y(s[key] || 0)); else ctx.moveTo(x, y(s[key] || 0));
        });
        ctx.stroke();
        const last = n ? this.samples[n - 1][key] : null;
        ctx.fillStyle = color; ctx.font = "11px sans-serif";
        ctx.fillText(`${label} ${A.fmt(last, 0)}%`, left + i * 78, 12);
      });
    },
  };

  if (graph.canvas) new ResizeObserver(() => graph.draw()).observe(graph.canvas);

  // Registered last: `onState` calls back at once when a state has already arrived, and everything it
  // uses (graph, events) must be initialised by then.
  A.onState((s) => {
    modeBtn.textContent = s.mode || "MANUAL";
    modeBtn.classList.toggle("on", s.mode === "AUTO");
    [$("state-agent").textContent, $("state-agent").title] = A.agentWords(s.agent_state);
    $("state-map").textContent = s.active_map || "—";
    localization(s.localization);
    leds($("level1"), s.level1);
    leds($("level2"), s.level2);
    const w = s.wheel_speeds || {};
    $("wheel-left").textContent = A.fmt(w.left_radps);
    $("wheel-right").textContent = A.fmt(w.right_radps);
    const em = $("emergency-led");
    em.className = `led ${s.emergency ? "bad blink" : "ok"}`;
    em.textContent = s.emergency ? "EMERGENCY" : "BRAKES OFF";
    graph.add(s.system);
    events(s.events);
    driveNote(s);
  });
})();
