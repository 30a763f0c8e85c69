// The operator's side of the call on the Control page: CALL rings the robot's screen; once it answers,
// the resident's video plays beside the drive camera, and MUTE, CAMERA OFF and END work on this side.
"use strict";

(function () {
  const A = window.ATEMR;
  const $ = (id) => document.getElementById(id);
  const video = $("call-video");
  const text = $("call-state");
  const start = $("call-start");
  const mute = $("call-mute");
  const camera = $("call-camera");
  const end = $("call-end");
  let peer = null;
  if (!A || !A.socket) return;
  A.LABELS.call_start = "Call";
  A.LABELS.call_end = "End call";
  A.STARTED.call_start = "ringing"; // begun, not done: the call's state says when it is answered
  A.ENDED_BY.call_start = /^call$/; // and then takes the place of "Call: ringing" ("Call: answered")

  function show(state, reason) {
    document.body.dataset.call = state;
    start.hidden = state !== "idle";
    end.hidden = state === "idle";
    mute.hidden = camera.hidden = video.hidden = state !== "active";
    text.textContent = state === "ringing" ? "Ringing the robot's screen…"
      : state === "active" ? "In a call with the robot's screen"
      : reason ? `No call: ${reason}` : "No call";
    if (state === "active") A.settle("call", "answered", true);
    else if (state === "idle") A.settle("call", reason || "ended", !reason);
  }

  function hangUp(reason) {
    if (peer) { peer.stop(); peer = null; }
    mute.classList.remove("on"); mute.textContent = "MUTE";
    camera.classList.remove("on"); camera.textContent = "CAMERA OFF";
    show("idle", reason);
  }

  A.socket.on("call_state", (s) => {
    if (s.state === "active" && !peer) {
      peer = new CallPeer((signal) => A.socket.emit("call_signal", signal), video, s.ice_servers);
      window.atemrCall = peer;
      peer.onFailed = () => { A.socket.emit("call_end"); hangUp("the call's connection failed"); };
      peer.start(true).catch((err) => { text.textContent = `Camera or microphone: ${err.message}`; });
      show("active", "");
    } else if (s.state === "idle") hangUp(s.reason);
    else show(s.state, s.reason);
  });
  A.socket.on("call_signal", (m) => { if (peer) peer.signal(m); });
  A.socket.on("disconnect", () => hangUp("the connection to the robot was lost"));

  start.addEventListener("click", async () => {
    const ack = await A.command("call_start");
    if (!ack.ok) text.textContent = `No call: ${ack.reason}`;
  });
  end.addEventListener("click", () => A.command("call_end"));
  mute.addEventListener("click", () => {
    const muted = mute.classList.toggle("on");
    mute.textContent = muted ? "UNMUTE" : "MUTE";
    if (peer) peer.enable("audio", !muted);
  });
  camera.addEventListener("click", () => {
    const off = camera.classList.toggle("on");
    camera.textContent = off ? "CAMERA ON" : "CAMERA OFF";
    if (peer) peer.enable("video", !off);
  });
  show("idle", "");
})();
