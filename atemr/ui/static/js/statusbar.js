// The status bar on every page (socket ONLINE/OFFLINE/ERROR, agent state, emergency) and the page-wide
// ATEMR object: the socket, the latest state, listeners, and `command(event, data)` with feedback.
//
// Several robots (ui.message_queue): each state names its robot (`robot`). States are kept per robot and
// the page shows the selected one; the status bar's robot selector appears when a second robot publishes
// (or when the one robot is not this dashboard's own). Commands go to this dashboard's own robot
// (<body data-robot>), so they are refused on the page while another robot is shown.
"use strict";

(function () {
  const listeners = [];
  const SUBSCRIPTIONS = new Set(["camera", "agent_view"]); // this dashboard's own views, not commands
  const STALE_MS = 5000; // a robot silent this long leaves the selector
  const ATEMR = {
    state: {},
    socket: null,
    onState(f) { listeners.push(f); if (Object.keys(this.state).length) f(this.state); },
    csrf: (document.querySelector('meta[name="csrf-token"]') || {}).content || "",
    own: document.body.dataset.robot || "", // this dashboard's robot ("" for a worker without one)
    robot: null, // the robot shown
    // Another robot than this dashboard's own is shown: commands are refused, its events settle nothing here.
    get watchingAnother() { return this.own !== "" && this.robot !== null && this.robot !== this.own; },
    // ``on_behalf``: the command a step is taken for, whose label reports it (GO HERE switches to AUTO first; a
    // refusal of that switch reads "Go here: ...", not "Mode: ..."). Nothing is reported of an accepted step.
    async command(event, data, on_behalf = null) {
      if (!this.socket) return { ok: false, reason: "no connection on this page" };
      const said = (ack) => {
        // a view subscribed to (the camera, the Agent view) shows itself when it works: only a refusal is said
        if (event === "joystick" || (ack.ok && (on_behalf || SUBSCRIPTIONS.has(event)))) return;
        this.report(on_behalf || event, ack, data);
      };
      if (this.watchingAnother && !SUBSCRIPTIONS.has(event)) {
        const ack = { ok: false, reason: `${this.robot} is only watched here: commands go to ${this.own}` };
        said(ack);
        return ack;
      }
      const ack = await this.socket.emit(event, data);
      said(ack);
      return ack;
    },
    // What each command is called on the page (the event names stay on the Agent page and in the logs).
    LABELS: {
      mode: "Mode", goal: "Go here", initial_pose: "Set position", localize_globally: "Find position",
      cancel_goal: "Stop", capture_image: "Capture", record_video: "Recording", mission_start: "Start mission",
      mission_stop: "Stop mission", mapping_begin: "Begin map", mapping_end: "End map", map_save: "Save map",
      map_discard: "Discard map", map_select: "Map", agent_reload: "Reload", autonomy_level: "Autonomy",
      autonomy_confirm: "Confirm", autonomy_deny: "Deny", sim_button: "Power button", sim_obstacle: "Drop obstacle",
      sim_kidnap: "Kidnap", camera: "Camera", agent_view: "Agent view", go_to_place: "Go to place",
      place_save: "Save place", place_delete: "Delete place",
    },
    // Commands that start something the robot then does for a while: their acknowledgement says it began, not
    // "done", which beside "On the way: 1.1 m left" read as the goal's outcome. An entry may also be a function of
    // the command's data, where the same command goes either way (RECORD starts or stops).
    STARTED: {
      goal: "accepted", go_to_place: "accepted", mission_start: "started", localize_globally: "searching",
      mapping_begin: "started",
    },
    // The robot's events that end what a started command began (`alerts.js` hands every new event to
    // `settle`): an acknowledgement left reading "Go here: accepted" beside "Goal failed" looks stale.
    ENDED_BY: {
      goal: /^(goal|unconfirmed)$/, go_to_place: /^(goal|unconfirmed)$/, mission_start: /^(mission|unconfirmed)$/,
      localize_globally: /^localization (localized|relocalized|ambiguous|failed)$/,
    },
    // Outcomes that are said but not final: an ambiguous search resolves once the robot is driven a little, a failed
    // one is tried again by itself; "The robot knows where it is" then takes their place.
    NOT_FINAL: /^localization (ambiguous|failed)$/,
    started: null, // the started command whose acknowledgement is shown, until its outcome comes
    report(what, ack, data = {}) {
      const label = this.LABELS[what] || what;
      if (!ack.ok && this.alert) this.alert(`${label}: ${ack.reason}`, "warning");
      const out = document.getElementById("command-result");
      if (!out) return;
      const started = typeof this.STARTED[what] === "function" ? this.STARTED[what](data || {}) : this.STARTED[what];
      out.textContent = ack.ok ? `${label}: ${started || "done"}` : `${label}: ${ack.reason}`;
      out.className = ack.ok ? "hint ok" : "hint error";
      this.started = ack.ok && this.ENDED_BY[what] ? what : null;
    },
    // The outcome of the started command shown (the event's words as the alert says them, and whether it went
    // well) replaces its acknowledgement. Other events leave it alone.
    settle(kind, text, ok) {
      const out = document.getElementById("command-result");
      if (!out || !this.started || !this.ENDED_BY[this.started].test(kind)) return;
      if (this.watchingAnother) return; // another robot's news
      out.textContent = `${this.LABELS[this.started]}: ${text}`;
      out.className = ok ? "hint ok" : "hint error";
      if (!this.NOT_FINAL.test(kind)) this.started = null;
    },
    fmt(v, digits = 2) { return typeof v === "number" && isFinite(v) ? v.toFixed(digits) : "—"; },
  };
  window.ATEMR = ATEMR;

  // Forms that destroy something ask first (no inline handlers: the CSP forbids them), and so does a
  // checkbox being switched on that makes the robot act by itself (data-confirm-on, e.g. awareness).
  document.addEventListener("submit", (e) => {
    const question = e.target.dataset && e.target.dataset.confirm;
    if (question && !window.confirm(question)) { e.preventDefault(); return; }
    for (const box of e.target.querySelectorAll ? e.target.querySelectorAll("input[data-confirm-on]") : []) {
      if (box.checked && !box.defaultChecked && !window.confirm(box.dataset.confirmOn)) { e.preventDefault(); return; }
    }
  }, true);

  const sock = document.getElementById("sock");
  const agent = document.getElementById("agent-state");
  const emergency = document.getElementById("emergency");

  // The bar in a carer's words; the engineer's names (the socket's status, the agent state) stay in data-status and
  // data-state for scripts and tests, and in each indicator's hover text.
  const CONNECTION = {
    ONLINE: ["Connected", "live: what the page shows is the robot now"],
    OFFLINE: ["Offline", "no connection to the robot; the page keeps trying"],
    ERROR: ["Refused", "the robot refused this page (logged out, or no access): log in again"],
  };
  function showStatus(status) {
    const [word, why] = CONNECTION[status] || [status, ""];
    sock.textContent = word;
    sock.dataset.status = status;
    sock.title = `the page's connection to the robot (WebSocket ${status}): ${why}`;
    sock.className = `ind ${status.toLowerCase()}`;
  }

  // What the robot's agent is doing (`RobotState.agent_state`), as a carer reads it.
  const AGENT_WORDS = {
    UNDEFINED: ["Starting up", "the robot has not reported yet"],
    STARTUP: ["Starting up", "checking its motors, sensors and map"],
    IDLE: ["Ready", "waiting: drive it, or send it to a place or on a mission"],
    EXEC: ["Busy", "driving to a goal or doing a mission"],
    MAPPING: ["Mapping", "learning the rooms as it is driven"],
    ERROR: ["Needs help", "a fault stopped it; see the alerts"],
    SHUTDOWN: ["Shutting down", "the robot is switching off"],
  };
  /** [words, hover text] for an agent state: the status bar's, and the Control page's drive panel's. */
  ATEMR.agentWords = (state) => {
    const [word, why] = AGENT_WORDS[state] || [state || "—", ""];
    return [word, state ? `${why} (agent state ${state})` : "agent state"];
  };
  // Why the robot is held stopped (`RobotState.stop_cause`), in two words; what to do is on hover (alerts.js).
  const STOPPED = { cliff: "a drop", floor_sensors: "floor sensors", obstacle: "too close", heartbeat: "lost contact",
                    motor: "motor fault", bus: "motors silent" };

  function showState(s) {
    [agent.textContent, agent.title] = ATEMR.agentWords(s.agent_state);
    agent.dataset.state = s.agent_state || "";
    if (s.stop_cause) {
      emergency.textContent = `Stopped: ${STOPPED[s.stop_cause] || s.stop_cause}`; emergency.className = "ind error";
      emergency.title = ATEMR.stopText ? ATEMR.stopText(s.stop_cause) : "";
    } else if (s.emergency === true) {
      emergency.textContent = "Emergency"; emergency.className = "ind error";
      emergency.title = "the brakes hold the robot (emergency stop)";
    } else if (s.emergency === false) {
      emergency.textContent = "No emergency"; emergency.className = "ind online";
      emergency.title = "no emergency: the brakes are off";
    }
    emergency.dataset.cause = s.stop_cause || (s.emergency === true ? "emergency" : s.emergency === false ? "" : "unknown");
    showAutonomy(s.autonomy);
    showBattery(s.battery);
  }

  // The battery's charge (estimated from the motors' supply voltage), on every page.
  function showBattery(b) {
    const battery = document.getElementById("battery");
    if (!battery) return;
    if (!b) { battery.textContent = "Battery —"; battery.className = "ind"; return; }
    battery.textContent = `Battery ${Math.round(b.percent)} %`;
    battery.className = `ind ${b.level === "ok" ? "online" : b.level === "low" ? "warning" : "error"}`;
    battery.title = `battery ${b.percent.toFixed(0)} % (${b.voltage_v.toFixed(1)} V)` +
      (b.level === "return" ? ": going home to charge" : b.level === "critical" ? ": critical, stopped" : "");
  }

  // Operator autonomy: the level in the bar, and a transition waiting for the operator with Confirm/Deny.
  const level = document.getElementById("autonomy-level");
  const request = document.getElementById("autonomy-request");
  // What each autonomy level (`atemr.fsm.autonomy.LEVELS`) lets the robot do without asking.
  const AUTONOMY_WORDS = {
    off: "off: it asks you before every step that can wait for an answer",
    low: "low: it asks you before most steps",
    high: "high: it asks you only before the steps marked for full autonomy",
    full: "full: it never waits for you (safety steps never wait at any level)",
  };
  function showAutonomy(a) {
    if (!a) { // a robot that does not report autonomy (another robot's dashboard): nothing to answer here
      level.textContent = "Autonomy —";
      if (request) request.hidden = true;
      return;
    }
    level.textContent = `Autonomy ${a.level || "—"}`;
    level.dataset.level = a.level || "";
    level.title = `${AUTONOMY_WORDS[a.level] || "the robot's autonomy level"} (the Agent page changes it)`;
    if (!request) return;
    const p = a.pending;
    request.hidden = !p;
    request.dataset.id = p ? String(p.id) : "";
    if (!p) return;
    const what = { goal: "drive to the goal", start_mission: "start the mission", set_auto: "switch to AUTO",
                   begin_mapping: "start mapping", cancel: "stop" }[p.trigger] || `go on (${p.trigger})`;
    const ask = document.getElementById("autonomy-what");
    ask.textContent = `may it ${what}?`;
    ask.title = `${p.trigger}: ${p.source} → ${p.dest}, needs autonomy ${p.level}`; // the technical words, on hover
    document.getElementById("autonomy-why").textContent =
      `It asks first at this autonomy level (${a.level})${p.origin ? `; asked from ${p.origin}` : ""}.`;
    const now = a.now;
    document.getElementById("autonomy-left").textContent =
      typeof now === "number" ? Math.max(0, p.deadline - now).toFixed(0) : `${a.timeout_s}`;
  }
  if (request) {
    for (const [id, event] of [["autonomy-confirm", "autonomy_confirm"], ["autonomy-deny", "autonomy_deny"]]) {
      document.getElementById(id).addEventListener("click", async () => {
        const rid = Number(request.dataset.id);
        if (!rid) return;
        const ack = await ATEMR.command(event, { id: rid });
        if (ack.ok) request.hidden = true;
        else document.getElementById("autonomy-why").textContent = ack.reason;
      });
    }
  }

  // -- robots -------------------------------------------------------------------------------------
  const robots = new Map(); // name → {state, seen (ms)}
  const picker = document.getElementById("robot");

  function deliver(s) {
    ATEMR.state = s || {};
    showState(ATEMR.state);
    for (const f of listeners) {
      try { f(ATEMR.state); } catch (err) { console.error(err); }
    }
  }

  function showRobots() {
    const names = [...robots.keys()].sort();
    picker.hidden = !(names.length > 1 || (names.length === 1 && names[0] !== ATEMR.own));
    const list = names.join("\n");
    if (picker.dataset.names !== list) {
      picker.dataset.names = list;
      picker.innerHTML = "";
      for (const n of names) {
        const o = document.createElement("option");
        o.value = n;
        o.textContent = n === ATEMR.own ? `${n || "robot"} (here)` : n || "robot";
        picker.appendChild(o);
      }
    }
    picker.value = ATEMR.robot ?? "";
    picker.classList.toggle("error", ATEMR.own !== "" && ATEMR.robot !== ATEMR.own);
  }

  function prune(now) {
    for (const [n, r] of robots) if (now - r.seen > STALE_MS) robots.delete(n);
    if (ATEMR.robot !== null && !robots.has(ATEMR.robot)) {
      const next = robots.has(ATEMR.own) ? ATEMR.own : [...robots.keys()].sort()[0];
      ATEMR.robot = next ?? null;
      if (next !== undefined) deliver(robots.get(next).state);
    }
    showRobots();
  }

  function received(s) {
    s = s || {};
    const name = typeof s.robot === "string" ? s.robot : ATEMR.own; // unnamed: this dashboard's robot
    const now = Date.now();
    robots.set(name, { state: s, seen: now });
    if (ATEMR.robot === null || (name === ATEMR.own && ATEMR.robot !== ATEMR.own && !picker.dataset.chosen)) {
      ATEMR.robot = name; // the first robot heard, or this dashboard's own as soon as it speaks
    }
    prune(now);
    if (name === ATEMR.robot) deliver(s);
  }

  picker.addEventListener("change", () => {
    picker.dataset.chosen = "1";
    ATEMR.robot = picker.value;
    const r = robots.get(ATEMR.robot);
    if (r) deliver(r.state);
    showRobots();
  });

  if (document.body.dataset.socket === "on") {
    ATEMR.socket = new AtemrSocket(showStatus);
    ATEMR.socket.on("state", received);
    setInterval(() => prune(Date.now()), 1000);
    fetch("/api/state", { headers: { Accept: "application/json" } })
      .then((r) => (r.ok ? r.json() : null))
      .then((s) => { if (s && s.connected && ATEMR.robot === null) received(s); })
      .catch(() => {});
  }
})();
