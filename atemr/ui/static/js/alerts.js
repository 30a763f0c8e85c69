// Connection truth and alerts, on every page with a socket.
//
// Connection truth: the robot sends its state every period (<body data-state-period-ms>). When none came for
// two periods, or the socket is down, the page says so in a banner with how long ago the last state came,
// greys out what it shows live (camera, map, indicators) and turns the drive controls off (ATEMR.live is
// false: the joystick sends nothing); when state comes back, it says that too.
//
// Alerts: what the carer must know, in plain words, as a toast that fades and in a list they can open
// (ALERTS in the status bar): refusals and failures of their commands, goals reached or failed, missions
// finished, why the robot is held stopped and what to do, localization lost or found, the robot offline.
"use strict";

(function () {
  const A = window.ATEMR;
  if (!A || !A.socket) return;
  const $ = (id) => document.getElementById(id);
  const PERIOD_MS = Number(document.body.dataset.statePeriodMs) || 100;
  const STALE_MS = 2 * PERIOD_MS;
  const FIRST_STATE_GRACE_MS = 3000; // a page just opened waits this long for its first state
  // The banner and the drive controls react after two periods (nothing is driven on old news), but the alert says
  // "offline" only once the silence lasts this long: a robot busy for a moment (a slow tick) is not offline, and
  // telling the carer so, then "back online", several times a minute would teach them to ignore the alerts.
  const OFFLINE_ALERT_MS = 1000;
  const TOAST_MS = 8000;
  const KEPT = 100;

  // -- alerts ---------------------------------------------------------------------------------------
  const toasts = $("alerts"), list = $("alert-items"), openBtn = $("alerts-open"), count = $("alerts-count");
  const dialog = $("alert-list");
  let unseen = 0;
  A.alert = function (text, level = "info") {
    const time = new Date().toLocaleTimeString();
    const toast = document.createElement("div");
    toast.className = `alert ${level}`;
    toast.setAttribute("role", level === "error" ? "alert" : "status");
    toast.textContent = text;
    const close = document.createElement("button");
    close.type = "button"; close.className = "alert-close"; close.textContent = "×";
    close.setAttribute("aria-label", "dismiss");
    close.addEventListener("click", () => toast.remove());
    toast.appendChild(close);
    toasts.prepend(toast);
    while (toasts.children.length > 3) toasts.lastChild.remove();
    if (level !== "error") setTimeout(() => toast.remove(), TOAST_MS);
    const item = document.createElement("li");
    item.className = `alert-item ${level}`;
    item.textContent = `${time}  ${text}`;
    list.prepend(item);
    while (list.children.length > KEPT) list.lastChild.remove();
    unseen += 1;
    count.textContent = String(unseen);
    openBtn.hidden = false;
    openBtn.classList.toggle("error", level === "error" || openBtn.classList.contains("error"));
    return toast;
  };
  openBtn.addEventListener("click", () => {
    unseen = 0; count.textContent = "0"; openBtn.classList.remove("error");
    dialog.showModal();
  });

  // -- the robot's events: each new one once, in plain words -----------------------------------------
  const eventListeners = [];
  A.onEvent = (f) => eventListeners.push(f);
  const seen = new Set();
  let primed = false; // the events already there when the page opened are history, not news
  // Localization's events (`atemr.skills.localization.localizer.EventKind`) worth telling a carer; the others
  // (a position set, a search started) are answered by the command's own feedback.
  const LOCALIZATION = {
    lost: ["The robot is no longer sure where it is. Set its position on the map (SET POSITION) or press FIND POSITION.", "warning"],
    relocalized: ["The robot knows where it is again.", "ok"],
    localized: ["The robot knows where it is.", "ok"],
    ambiguous: ["Places on the map look alike to the robot (drawn on the map). Drive it a little so that it can tell them apart, or set its position (SET POSITION).", "warning"],
    failed: ["The robot could not find where it is. Set its position on the map (SET POSITION), or drive it a little and press FIND POSITION again.", "warning"],
    pose_refused: ["What the robot sees does not fit the position you set, so it is searching the whole map. Wait, or set the position again.", "warning"],
    map_changed: ["Another map is in use: the robot does not know where it is on it. Set its position (SET POSITION) or press FIND POSITION.", "warning"],
    initial_pose: null,
    global_start: null,
  };
  const LOOKING = ["Places on the map look alike to the robot (drawn on the map). It is turning in place to look around; if it stays unsure, drive it a little or set its position (SET POSITION).", "warning"];
  function plain(e) {
    const kind = String(e.kind || "");
    if (kind === "goal" || kind === "mission") {
      return [e.text, /reached|finished/.test(e.text) ? "ok" : "warning"];
    }
    if (kind.startsWith("localization ")) {
      const what = kind.slice("localization ".length);
      // after FIND POSITION the robot turns in place by itself to tell the places apart (the event says so)
      if (what === "ambiguous" && /turning in place/.test(e.text)) return LOOKING;
      return what in LOCALIZATION ? LOCALIZATION[what] : [`Localization: ${e.text}`, "info"];
    }
    if (kind === "refused" || kind === "unconfirmed") return [e.text, "warning"];
    if (kind === "battery") return [e.text, /critical/.test(e.text) ? "error" : "warning"];
    if (kind === "routine") return [`Routine ${e.text}`, /skipped|missed|failed|refused|cancelled/.test(e.text) ? "warning" : "ok"];
    // The heartbeat, a motor and the CAN bus stop the robot: the carer reads that once, in plain words, from the
    // state's stop_cause (below), and "may move again" when it clears. These events' own text ("0x157 heartbeat
    // lost", "left_motor ...") is the engineer's, kept in the Events list.
    if (kind === "heartbeat" || kind === "motor fault" || kind === "can bus") return null;
    if (kind === "component error") return [e.text, "error"];
    return null; // settings, media, maps, autonomy: in the Events list, not worth interrupting for
  }
  A.plainEvent = plain; // the Events list (panel.js) shows an event in these words where there are some
  A.onState((s) => {
    for (const e of Array.isArray(s.events) ? s.events : []) {
      const key = `${e.t}|${e.kind}|${e.text}`;
      if (seen.has(key)) continue;
      seen.add(key);
      if (!primed) continue;
      for (const f of eventListeners) { try { f(e); } catch (err) { console.error(err); } }
      const said = plain(e);
      if (said) {
        A.alert(said[0], said[1]);
        A.settle(String(e.kind || ""), said[0], said[1] === "ok");
      }
    }
    primed = true;
  });

  // -- why the robot is held stopped, and what to do ----------------------------------------------------
  const STOPS = {
    cliff: "Stopped: a drop (stairs, a step) is under the robot's edge. Drive it back, away from the edge.",
    floor_sensors: "Stopped: the floor sensors that watch for stairs have gone quiet, so the robot cannot tell where a drop is. It moves again when they report; if not, restart it.",
    obstacle: "Stopped: something is too close. Drive away from it: reverse or turn.",
    heartbeat: "Stopped: the robot's two computers lost contact. It moves again when they talk again; if not, restart it.",
    motor: "Stopped: a motor reports a fault. The robot moves again when both motors answer without error.",
    bus: "Stopped: the motors' connection (CAN bus) failed. The robot moves again when it works again.",
  };
  let cause = null;
  A.stopText = (c) => STOPS[c] || "";
  A.onState((s) => {
    const now = s.stop_cause ?? null;
    if (now === cause) return;
    if (now) A.alert(STOPS[now] || `Stopped: ${now}.`, "error");
    else if (cause) A.alert("The robot may move again.", "ok");
    cause = now;
  });

  // -- connection truth ---------------------------------------------------------------------------------
  const banner = $("connection");
  const opened = Date.now();
  let lastAt = null;
  let connected = false; // the socket has been ONLINE at least once
  let stale = false;
  let backTimer = null;
  let offline = null; // the offline alert, taken down when the robot is back
  A.live = true;
  A.onState(() => { lastAt = Date.now(); check(); });

  function setDrive(enabled) {
    for (const el of document.querySelectorAll("[data-drive]")) {
      if ("disabled" in el && el.tagName !== "DIV") el.disabled = !enabled;
      el.setAttribute("aria-disabled", enabled ? "false" : "true");
    }
  }

  function check() {
    const now = Date.now();
    const online = A.socket.status === "ONLINE";
    // A page just opened is still connecting (its first state may come over HTTP before the socket is up): it
    // is stale only once the socket or the first state is overdue.
    if (online) connected = true;
    const opening = (!connected || lastAt === null) && now - opened <= FIRST_STATE_GRACE_MS;
    const nowStale = !opening && (!online || lastAt === null || now - lastAt > STALE_MS);
    if (nowStale) {
      const silentMs = now - (lastAt ?? opened);
      if (!offline && silentMs >= OFFLINE_ALERT_MS) {
        offline = A.alert("The robot is offline: no state is coming. Driving is off until it is back.", "error");
      }
      const ago = lastAt === null ? "no state has come yet" : `the last state came ${((now - lastAt) / 1000).toFixed(1)} s ago`;
      const why = online ? "No news from the robot" : "The connection to the robot is lost";
      banner.textContent = `${why}: ${ago}. What you see is old, and driving is off.`;
      banner.className = "connection stale";
      banner.hidden = false;
      if (backTimer) { clearTimeout(backTimer); backTimer = null; }
    }
    if (nowStale === stale) return;
    stale = nowStale;
    A.live = !stale;
    document.body.classList.toggle("stale", stale);
    setDrive(!stale);
    if (!stale) {
      banner.textContent = "Connected again: the robot's state is live.";
      banner.className = "connection back";
      backTimer = setTimeout(() => { banner.hidden = true; }, 3000);
      if (offline) { // said only after the offline alert: a short silence came and went without one
        offline.remove(); offline = null;
        A.alert("The robot is back online.", "ok");
      }
    }
  }
  setInterval(check, Math.min(100, PERIOD_MS));

  // Resolves when the robot's state satisfies `pred` (or after `ms`, with false).
  A.until = (pred, ms) => new Promise((resolve) => {
    const t0 = Date.now();
    const poll = () => {
      if (pred(A.state)) resolve(true);
      else if (Date.now() - t0 > ms) resolve(false);
      else setTimeout(poll, 50);
    };
    poll();
  });
})();
