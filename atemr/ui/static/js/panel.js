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

  function leds(el, states) {
    if (!el) return;
    const entries = Object.entries(states || {});
    el.innerHTML = "";
    for (const [name, ok] of entries) {
      const span = document.createElement("span");
      span.className = `led ${ok ? "ok" : "bad"}`;
      span.textContent = name.replace(/_/g, " ").toUpperCase();
      if (name.toLowerCase() === "auto") { span.className = "led mode"; span.textContent = `M/A ${ok ? "AUTO" : "MANUAL"}`; }
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
      : `${loc.state}${places ? `: ${places} places look alike (drawn on the map); move the robot or set its pose` : ""}; ` +
        `needs ${pct(loc.limit)} — set the pose or FIND POSE`;
  }

  $("level2-toggle").addEventListener("click", () => { $("level2").hidden = !$("level2").hidden; });
  $("graph-toggle").addEventListener("click", () => { $("sysgraph").hidden = !$("sysgraph").hidden; });


  // -- the latest events, newest first -------------------------------------------------------------
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
      li.textContent = `${A.fmt(e.t, 1)} s  ${e.kind || ""}: ${e.text || ""}`;
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
    A.command("joystick", { linear_mps: c.linear_mps, angular_radps: c.angular_radps });
  }

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
  pad.addEventListener("pointerdown", (e) => { pad.setPointerCapture(e.pointerId); joy.pointer = true; fromPointer(e); update(); });
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
      const ctx = c.getContext("2d");
      ctx.clearRect(0, 0, c.width, c.height);
      ctx.strokeStyle = "#d0d7de"; ctx.lineWidth = 1;
      for (const p of [25, 50, 75]) { const y = c.height * (1 - p / 100); ctx.beginPath(); ctx.moveTo(0, y); ctx.lineTo(c.width, y); ctx.stroke(); }
      const series = [["cpu_percent", "#cf222e", "CPU"], ["memory_percent", "#1f6feb", "MEM"], ["disk_percent", "#2da44e", "DISK"]];
      const n = this.samples.length;
      series.forEach(([key, color, label], i) => {
        ctx.strokeStyle = color; ctx.lineWidth = 2; ctx.beginPath();
        this.samples.forEach((s, j) => {
          const x = c.width - (n - 1 - j) * (c.width / 119);
          const y = c.height * (1 - (s[key] || 0) / 100);
          if (j) ctx.lineTo(x, y); else ctx.moveTo(x, y);
        });
        ctx.stroke();
        const last = n ? this.samples[n - 1][key] : null;
        ctx.fillStyle = color; ctx.font = "11px sans-serif";
        ctx.fillText(`${label} ${A.fmt(last, 0)}%`, 4 + i * 80, 12);
      });
    },
  };

  // Registered last: `onState` calls back at once when a state has already arrived, and everything it
  // uses (graph, events) must be initialised by then.
  A.onState((s) => {
    modeBtn.textContent = s.mode || "MANUAL";
    modeBtn.classList.toggle("on", s.mode === "AUTO");
    $("state-agent").textContent = s.agent_state || "—";
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
  });
})();
