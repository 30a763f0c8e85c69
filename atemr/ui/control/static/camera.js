// The drive camera on the Control page, by the lowest-latency transport that works:
//   1. WebRTC: GET /api/drive-video says whether to try (and why not); the page offers to receive one video
//      track, the robot answers over the socket (drive_video_offer) and sends its camera with aiortc;
//   2. MJPEG (/api/camera.mjpeg, an <img> the browser decodes) when WebRTC cannot be had or fails: refused,
//      no first frame within FIRST_FRAME_MS, or a connection that fails;
//   3. JPEG frames over the Socket.IO connection (the "camera" subscription) when the MJPEG stream cannot
//      be loaded.
// The badge on the camera says which ("WebRTC", "MJPEG", "Socket.IO") and, on hover, why not WebRTC.
// CAM-OFF closes the WebRTC connection or drops the stream, so the robot stops sending.
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const A = window.ATEMR;
  const img = $("camera"), video = $("camera-video"), camOff = $("camera-off"), camBtn = $("cam-toggle");
  const badge = $("camera-transport");
  const MJPEG = "/api/camera.mjpeg";
  const NAMES = { webrtc: "WebRTC", mjpeg: "MJPEG", socket: "Socket.IO" };
  const FIRST_FRAME_MS = 8000; // a connection that shows no picture by then falls back to MJPEG
  const GATHER_MS = 3000; // the offer goes with the candidates gathered by then
  let transport = null; // "webrtc" | "mjpeg" | "socket"; null until /api/drive-video answered
  let whyNot = ""; // why not WebRTC, in the page's words
  let iceServers = [];
  let camOn = false;
  let camWanted = true; // CAM-ON by default (thesis 3.5.3); off saves bandwidth
  let camPending = false;
  let peer = null; // the WebRTC connection while there is one
  let attempt = 0; // each WebRTC start counts; an older one that finishes late gives up

  function show(on) {
    camOn = on;
    camBtn.textContent = on ? "CAM-ON" : "CAM-OFF";
    camBtn.classList.toggle("on", on);
    img.hidden = !on || transport === "webrtc";
    video.hidden = !on || transport !== "webrtc";
    camOff.hidden = on;
    img.dataset.transport = transport || "";
    document.body.dataset.driveVideo = transport || "";
    badge.hidden = !on || !transport;
    badge.textContent = NAMES[transport] || "";
    badge.title = transport === "webrtc" ? "the camera comes over WebRTC"
      : whyNot ? `not WebRTC: ${whyNot}` : "";
    badge.dataset.why = transport === "webrtc" ? "" : whyNot;
  }

  // -- WebRTC ------------------------------------------------------------------------------------------
  function closePeer() {
    if (!peer) return;
    peer.close();
    peer = null;
    video.srcObject = null;
  }

  function gathered(pc) {
    if (pc.iceGatheringState === "complete") return Promise.resolve();
    return new Promise((done) => {
      const timer = setTimeout(done, GATHER_MS);
      pc.addEventListener("icegatheringstatechange", () => {
        if (pc.iceGatheringState === "complete") { clearTimeout(timer); done(); }
      });
    });
  }

  function firstFrame(pc) {
    return new Promise((done, fail) => {
      const started = Date.now();
      const look = () => {
        if (peer !== pc) return fail(new Error("stopped"));
        if (video.readyState >= 2 && video.videoWidth > 0) return done();
        if (Date.now() - started > FIRST_FRAME_MS) {
          return fail(new Error(`no picture within ${FIRST_FRAME_MS / 1000} s (connection ${pc.connectionState})`));
        }
        setTimeout(look, 100);
      };
      look();
    });
  }

  async function startWebrtc() {
    const mine = ++attempt;
    closePeer();
    const pc = new RTCPeerConnection({ iceServers });
    peer = pc;
    pc.addTransceiver("video", { direction: "recvonly" });
    pc.ontrack = (e) => {
      video.srcObject = new MediaStream([e.track]);
      video.play().catch(() => {}); // muted video plays without a tap
    };
    pc.onconnectionstatechange = () => {
      if (pc.connectionState !== "failed" || peer !== pc) return;
      if (A.socket.status === "ONLINE") fallBack("the WebRTC connection failed");
      else closePeer(); // the socket is down too: a new connection is offered once it is back
    };
    await pc.setLocalDescription(await pc.createOffer());
    await gathered(pc);
    if (mine !== attempt) return;
    const ack = await A.socket.emit("drive_video_offer",
      { description: { type: "offer", sdp: pc.localDescription.sdp } });
    if (mine !== attempt || peer !== pc) return; // CAM-OFF, a reconnect or a newer start meanwhile
    if (!ack.ok) throw new Error(ack.reason);
    await pc.setRemoteDescription(ack.description);
    await firstFrame(pc);
  }

  function stopWebrtc() {
    attempt++;
    if (peer) A.socket.emit("drive_video_stop");
    closePeer();
  }

  function fallBack(reason) {
    if (transport !== "webrtc") return;
    stopWebrtc();
    whyNot = reason;
    transport = "mjpeg";
    console.info(`drive camera: MJPEG, not WebRTC: ${reason}`);
    setCamera(camWanted);
  }

  // -- MJPEG and Socket.IO frames ----------------------------------------------------------------------
  img.addEventListener("error", () => {
    if (transport !== "mjpeg" || !img.getAttribute("src")) return;
    transport = "socket";
    img.removeAttribute("src");
    show(false);
    setCamera(camWanted);
  });
  A.socket.on("camera", (f) => {
    if (transport === "socket" && camOn && f && f.jpeg) img.src = `data:image/jpeg;base64,${f.jpeg}`;
  });

  async function decide() {
    try {
      const r = await fetch("/api/drive-video", { credentials: "same-origin", headers: { Accept: "application/json" } });
      const d = await r.json();
      iceServers = d.ice_servers || [];
      whyNot = d.webrtc ? "" : d.reason;
      if (d.webrtc && !window.RTCPeerConnection) whyNot = "this browser has no WebRTC";
      return d.webrtc && !whyNot ? "webrtc" : "mjpeg";
    } catch (err) {
      whyNot = `the robot did not say whether it sends WebRTC (${err.message})`;
      return "mjpeg";
    }
  }

  async function setCamera(on) {
    if (transport === null) {
      camPending = true;
      const chosen = await decide();
      camPending = false;
      if (transport === null) transport = chosen;
    }
    if (transport === "webrtc") {
      if (!on) { stopWebrtc(); show(false); return; }
      show(true);
      startWebrtc().catch((err) => {
        if (err.message === "stopped") return;
        if (A.socket.status !== "ONLINE") { closePeer(); return; } // offered again once the socket is back
        fallBack(err.message);
      });
      return;
    }
    if (transport === "mjpeg") {
      if (on) img.src = `${MJPEG}?t=${Date.now()}`; // a new stream (also after a reconnect)
      else img.removeAttribute("src"); // the browser drops the stream: the server stops reading frames
      show(on);
      return;
    }
    camPending = true;
    const ack = await A.command("camera", { on });
    camPending = false;
    if (ack.ok) show(on);
  }

  camBtn.addEventListener("click", () => { camWanted = !camOn; setCamera(camWanted); });
  A.socket.on("connect", () => setCamera(camWanted));
  // The robot closed the WebRTC connection with the socket: a new one is offered once it is back.
  A.socket.on("disconnect", () => { if (transport === "webrtc") { attempt++; closePeer(); } });
  // Self-healing: a subscription lost on the way (reconnect, a refused ack) is asked for again.
  A.onState(() => {
    if (transport === "socket" && camWanted !== camOn && !camPending && A.socket.status === "ONLINE") setCamera(camWanted);
  });

  // What the page receives over WebRTC (for tests and the latency benchmark): inbound video counters.
  window.atemrDriveVideo = {
    get transport() { return transport; },
    get whyNot() { return whyNot; },
    async stats() {
      if (!peer) return null;
      let out = null;
      (await peer.getStats()).forEach((r) => {
        if (r.type === "inbound-rtp" && r.kind === "video") {
          out = { bytesReceived: r.bytesReceived || 0, packetsReceived: r.packetsReceived || 0,
                  framesDecoded: r.framesDecoded || 0, state: peer.connectionState };
        }
      });
      return out;
    },
  };
})();
