// One side of the call's WebRTC link (the operator's Control page and the robot's screen alike): the
// camera and microphone from getUserMedia, the RTCPeerConnection with the ICE servers the robot sent, and
// the signals (offer, answer, ICE candidates) passed through `send`. The operator's side makes the offer.
// Signals are handled one after another, after the local media is ready, so an offer that arrives while
// the camera is still opening waits instead of being answered without tracks.
"use strict";

class CallPeer {
  constructor(send, remoteVideo, iceServers) {
    this.send = send;
    this.video = remoteVideo;
    this.iceServers = iceServers || [];
    this.pc = null;
    this.local = null;
    this.chain = Promise.resolve();
    this.early = []; // candidates that came before the remote description
    this.onFailed = () => {}; // the media link broke (the other side went without a word: this socket was down)
  }

  // Open the camera and microphone and the connection; the offerer also sends its offer.
  start(offerer) {
    this.chain = this.chain.then(async () => {
      this.local = await navigator.mediaDevices.getUserMedia({ audio: true, video: true });
      const pc = new RTCPeerConnection({ iceServers: this.iceServers });
      this.pc = pc;
      for (const track of this.local.getTracks()) pc.addTrack(track, this.local);
      pc.ontrack = (e) => {
        if (this.video.srcObject !== e.streams[0]) {
          this.video.srcObject = e.streams[0];
          this.video.play().catch(() => {}); // autoplay refused: the first tap plays it
        }
      };
      pc.onconnectionstatechange = () => { if (pc.connectionState === "failed") this.onFailed(); };
      pc.onicecandidate = (e) => this.send({ candidate: e.candidate ? e.candidate.toJSON() : null });
      if (offerer) {
        await pc.setLocalDescription(await pc.createOffer());
        this.send({ description: { type: pc.localDescription.type, sdp: pc.localDescription.sdp } });
      }
    });
    return this.chain;
  }

  // An offer, answer or candidate from the other side.
  signal(m) {
    this.chain = this.chain.then(async () => {
      const pc = this.pc;
      if (!pc) return;
      if (m.description) {
        await pc.setRemoteDescription(m.description);
        if (m.description.type === "offer") {
          await pc.setLocalDescription(await pc.createAnswer());
          this.send({ description: { type: pc.localDescription.type, sdp: pc.localDescription.sdp } });
        }
        for (const c of this.early.splice(0)) await pc.addIceCandidate(c);
      } else if (m.candidate) {
        if (pc.remoteDescription) await pc.addIceCandidate(m.candidate);
        else this.early.push(m.candidate);
      }
    }).catch((err) => console.warn("call signal", err));
    return this.chain;
  }

  // Mute the microphone or turn the camera off (the track stays, so nothing is renegotiated).
  enable(kind, on) {
    for (const t of this.local ? this.local.getTracks() : []) if (t.kind === kind) t.enabled = on;
  }

  stop() {
    if (this.pc) this.pc.close();
    for (const t of this.local ? this.local.getTracks() : []) t.stop();
    this.pc = null;
    this.local = null;
    this.video.srcObject = null;
  }

  // What came in so far, per kind: bytes, packets and (video) frames decoded.
  async stats() {
    const out = { audio: null, video: null, state: this.pc ? this.pc.connectionState : "closed" };
    if (!this.pc) return out;
    (await this.pc.getStats()).forEach((r) => {
      if (r.type === "inbound-rtp" && (r.kind === "audio" || r.kind === "video")) {
        out[r.kind] = { bytesReceived: r.bytesReceived || 0, packetsReceived: r.packetsReceived || 0,
                        framesDecoded: r.framesDecoded || 0 };
      }
    });
    return out;
  }
}

window.CallPeer = CallPeer;
