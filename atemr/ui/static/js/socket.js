// A small Socket.IO (protocol 5) client over Engine.IO 4 WebSocket transport: no build step, no CDN.
// Same origin only (the server refuses other origins). Status: OFFLINE, ONLINE, ERROR (refused).
"use strict";

class AtemrSocket {
  constructor(onStatus) {
    this.handlers = {};
    this.acks = {};
    this.ackId = 0;
    this.status = "OFFLINE";
    this.onStatus = onStatus || (() => {});
    this.retryMs = 1000;
    this.refused = false;
    this.open();
  }

  open() {
    const proto = location.protocol === "https:" ? "wss" : "ws";
    const ws = new WebSocket(`${proto}://${location.host}/socket.io/?EIO=4&transport=websocket`);
    this.ws = ws;
    ws.onmessage = (e) => this.packet(String(e.data));
    // A connection that fails (the robot's process ended, the network dropped) is OFFLINE, tried again; ERROR is
    // kept for a refusal (the connect packet answered "4": logged out, no access).
    ws.onerror = () => { if (!this.refused) this.setStatus("OFFLINE"); };
    ws.onclose = () => {
      if (this.status === "ONLINE") this.setStatus("OFFLINE");
      for (const id of Object.keys(this.acks)) {
        this.acks[id]({ ok: false, reason: "the connection to the robot was lost" });
        delete this.acks[id];
      }
      const delay = this.refused ? 10000 : this.retryMs;
      this.retryMs = Math.min(this.retryMs * 2, 5000);
      setTimeout(() => this.open(), delay);
    };
  }

  setStatus(status) {
    if (this.status !== status) {
      this.status = status;
      this.onStatus(status);
    }
  }

  packet(data) {
    const type = data[0];
    if (type === "0") this.ws.send("40"); // engine.io open → connect the default namespace
    else if (type === "2") this.ws.send("3"); // ping → pong
    else if (type === "4") this.message(data.slice(1));
  }

  message(p) {
    const type = p[0];
    const rest = p.slice(1);
    if (type === "0") {
      this.refused = false;
      this.retryMs = 1000;
      this.setStatus("ONLINE");
      this.fire("connect", null);
    } else if (type === "4") {
      this.refused = true; // connect refused: no session (logged out or no access)
      this.setStatus("ERROR");
      this.fire("refused", rest ? JSON.parse(rest) : null);
    } else if (type === "1") {
      this.setStatus("OFFLINE");
      this.fire("disconnect", null);
    } else if (type === "2" || type === "3") {
      const m = /^(\d*)([\s\S]*)$/.exec(rest);
      const args = JSON.parse(m[2]);
      if (type === "2") this.fire(args[0], args[1]);
      else if (this.acks[m[1]]) {
        const cb = this.acks[m[1]];
        delete this.acks[m[1]];
        cb(args[0]);
      }
    }
  }

  fire(event, data) {
    for (const f of this.handlers[event] || []) {
      try { f(data); } catch (err) { console.error(`handler of ${event}`, err); }
    }
  }

  on(event, f) {
    (this.handlers[event] = this.handlers[event] || []).push(f);
    // A page's later scripts can register after the connection opened: the browser delivers the socket's
    // messages while it waits for them to download (seen under load: the Control page's camera never started).
    // They are told at once, as they would have been.
    if (event === "connect" && this.status === "ONLINE") {
      queueMicrotask(() => {
        try { f(null); } catch (err) { console.error(`handler of ${event}`, err); }
      });
    }
  }

  // emit(event, data) → Promise of the acknowledgement {ok, reason}
  emit(event, data) {
    return new Promise((resolve) => {
      if (!this.ws || this.ws.readyState !== WebSocket.OPEN || this.status !== "ONLINE") {
        resolve({ ok: false, reason: "not connected to the robot" });
        return;
      }
      const id = String(++this.ackId);
      this.acks[id] = resolve;
      const args = data === undefined ? [event] : [event, data];
      this.ws.send("42" + id + JSON.stringify(args));
    });
  }
}

window.AtemrSocket = AtemrSocket;
