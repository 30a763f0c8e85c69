// The robot's screen: what the robot does and its charge in plain words, the caller's video, ANSWER / DECLINE /
// HANG UP.
// Its socket is the screen's (a device token's session): it gets `screen_state` and the call's events.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const words = $("robot-words");
  const callText = $("call-state");
  const buttons = { answer: $("answer"), decline: $("decline"), hangup: $("hangup") };
  let peer = null;
  let caller = "";

  const sock = new AtemrSocket((status) => {
    $("sock").textContent = status === "ONLINE" ? "" : "Not connected to the robot";
    $("sock").hidden = status === "ONLINE";
  });
  const send = (signal) => sock.emit("screen_signal", signal);

  // Why the last call ended stays this long, then the screen says "No call" again: in the screen's largest type,
  // "No call (you declined the call)" read as news hours later. <body data-call-reason-ms> may shorten it.
  // The call's state comes again and again; only a change is shown (and starts that while).
  let settle = null, shown = null;
  function show(state, reason) {
    const key = `${state}|${reason || ""}|${caller || ""}`;
    if (key === shown) return;
    shown = key;
    document.body.dataset.call = state;
    buttons.answer.hidden = buttons.decline.hidden = state !== "ringing";
    buttons.hangup.hidden = state !== "active";
    callText.textContent = state === "ringing" ? `${caller || "Someone"} is calling`
      : state === "active" ? `In a call with ${caller || "your carer"}`
      : reason ? `No call (${reason})` : "No call";
    clearTimeout(settle);
    if (state === "idle" && reason) {
      settle = setTimeout(() => { callText.textContent = "No call"; },
                          Number(document.body.dataset.callReasonMs) || 20000);
    }
  }

  const battery = $("battery");
  sock.on("screen_state", (s) => {
    words.textContent = s.words || "—";
    battery.textContent = s.battery || "";  // the charge, as on every dashboard page
    battery.dataset.level = s.battery_level || "";
  });
  sock.on("call_state", (s) => {
    caller = s.caller || caller;
    if (s.state === "active" && !peer) {
      peer = new CallPeer(send, $("remote"), s.ice_servers);
      window.atemrCall = peer;
      peer.onFailed = () => {
        sock.emit("screen_hangup");
        if (peer) { peer.stop(); peer = null; }
        show("idle", "the call's connection failed");
      };
      peer.start(false).catch((err) => { callText.textContent = `Camera or microphone: ${err.message}`; });
    } else if (s.state !== "active" && peer) {
      peer.stop();
      peer = null;
    }
    show(s.state, s.reason);
  });
  sock.on("call_signal", (m) => { if (peer) peer.signal(m); });
  sock.on("disconnect", () => { if (peer) { peer.stop(); peer = null; } show("idle", "the connection was lost"); });

  async function act(event) {
    const ack = await sock.emit(event);
    if (!ack.ok) callText.textContent = ack.reason;
  }
  buttons.answer.addEventListener("click", () => act("screen_answer"));
  buttons.decline.addEventListener("click", () => act("screen_decline"));
  buttons.hangup.addEventListener("click", () => act("screen_hangup"));
  show("idle", "");
})();
