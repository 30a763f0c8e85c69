// The map canvas: the occupancy grid image, robot pose, lidar points, global/local path, goal and the named
// places (a labelled marker each), with
// pan (drag), zoom (wheel, pinch, +/- keys) and a "command" mode in which press-drag-release gives a pose
// (position at the press, heading along the drag) to a callback: initial pose, goal, kidnap.
"use strict";

class MapView {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.meta = null;          // {width_px, height_px, resolution_m, origin:{x_m,y_m}, version}
    this.image = null;
    this.version = null;
    this.state = {};
    this.scale = 50;           // screen px per metre
    this.cx = 0; this.cy = 0;  // world point at the canvas centre
    this.commandMode = false;  // false: pan/zoom; true: press-drag gives a pose
    this.onPose = null;        // callback(pose) in command mode
    this.pending = null;       // a goal waiting for the operator's confirmation, drawn dashed
    this.drag = null;
    this.pointers = new Map();
    this.fitted = false;
    this.bind();
    this.resize();
    new ResizeObserver(() => this.resize()).observe(canvas);
  }

  resize() {
    const r = this.canvas.getBoundingClientRect();
    if (r.width > 0 && r.height > 0) { // crisp on phones and tablets: as many pixels as the screen has
      const ratio = window.devicePixelRatio || 1;
      this.canvas.width = Math.round(r.width * ratio);
      this.canvas.height = Math.round(r.height * ratio);
    }
    this.draw();
  }

  // -- coordinates -------------------------------------------------------------------------------
  toScreen(x, y) {
    return [this.canvas.width / 2 + (x - this.cx) * this.scale, this.canvas.height / 2 - (y - this.cy) * this.scale];
  }

  toWorld(sx, sy) {
    return [this.cx + (sx - this.canvas.width / 2) / this.scale, this.cy - (sy - this.canvas.height / 2) / this.scale];
  }

  eventPoint(e) {
    const r = this.canvas.getBoundingClientRect();
    return [(e.clientX - r.left) * (this.canvas.width / r.width), (e.clientY - r.top) * (this.canvas.height / r.height)];
  }

  reset() {
    if (this.meta) {
      const w = this.meta.width_px * this.meta.resolution_m;
      const h = this.meta.height_px * this.meta.resolution_m;
      this.cx = this.meta.origin.x_m + w / 2;
      this.cy = this.meta.origin.y_m + h / 2;
      this.scale = Math.max(1, Math.min(this.canvas.width / w, this.canvas.height / h) * 0.95);
    } else {
      const p = this.state.pose;
      this.cx = p ? p.x_m : 0; this.cy = p ? p.y_m : 0; this.scale = 50;
    }
    this.draw();
  }

  zoom(factor, sx, sy) {
    const [wx, wy] = this.toWorld(sx, sy);
    this.scale = Math.max(2, Math.min(2000, this.scale * factor));
    const [nx, ny] = this.toWorld(sx, sy);
    this.cx += wx - nx; this.cy += wy - ny;
    this.draw();
  }

  // -- input -------------------------------------------------------------------------------------
  bind() {
    const c = this.canvas;
    c.style.touchAction = "none";
    c.addEventListener("pointerdown", (e) => {
      c.setPointerCapture(e.pointerId);
      this.pointers.set(e.pointerId, this.eventPoint(e));
      const [sx, sy] = this.eventPoint(e);
      if (this.pointers.size === 2) { this.drag = { pinch: this.pinchDistance() }; return; }
      this.drag = { sx, sy, cx: this.cx, cy: this.cy, start: this.toWorld(sx, sy), end: null };
    });
    c.addEventListener("pointermove", (e) => {
      const [sx, sy] = this.eventPoint(e);
      const [wx, wy] = this.toWorld(sx, sy);
      const cursor = document.getElementById("map-cursor");
      if (cursor) cursor.textContent = `x ${wx.toFixed(2)} m, y ${wy.toFixed(2)} m`;
      if (!this.pointers.has(e.pointerId) || !this.drag) return;
      this.pointers.set(e.pointerId, [sx, sy]);
      if (this.drag.pinch) {
        const d = this.pinchDistance();
        if (d > 0 && this.drag.pinch > 0) this.zoom(d / this.drag.pinch, c.width / 2, c.height / 2);
        this.drag.pinch = d;
      } else if (this.commandMode) {
        this.drag.end = [wx, wy];
        this.draw();
      } else {
        this.cx = this.drag.cx - (sx - this.drag.sx) / this.scale;
        this.cy = this.drag.cy + (sy - this.drag.sy) / this.scale;
        this.draw();
      }
    });
    const up = (e) => {
      const drag = this.drag;
      this.pointers.delete(e.pointerId);
      if (!drag || drag.pinch) { if (this.pointers.size === 0) this.drag = null; return; }
      this.drag = null;
      if (this.commandMode && this.onPose && e.type === "pointerup") {
        const [x, y] = drag.start;
        const end = drag.end || drag.start;
        const moved = Math.hypot(end[0] - x, end[1] - y) > 2 / this.scale;
        const yaw = moved ? Math.atan2(end[1] - y, end[0] - x) : 0;
        this.onPose({ x_m: x, y_m: y, yaw_rad: yaw });
      }
      this.draw();
    };
    c.addEventListener("pointerup", up);
    c.addEventListener("pointercancel", up);
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      const [sx, sy] = this.eventPoint(e);
      this.zoom(e.deltaY < 0 ? 1.15 : 1 / 1.15, sx, sy);
    }, { passive: false });
    c.addEventListener("keydown", (e) => {
      if (e.key === "+" || e.key === "=") this.zoom(1.2, c.width / 2, c.height / 2);
      else if (e.key === "-") this.zoom(1 / 1.2, c.width / 2, c.height / 2);
    });
  }

  pinchDistance() {
    const pts = [...this.pointers.values()];
    return pts.length < 2 ? 0 : Math.hypot(pts[0][0] - pts[1][0], pts[0][1] - pts[1][1]);
  }

  // -- data --------------------------------------------------------------------------------------
  update(state) {
    this.state = state || {};
    const version = this.state.map_version;
    if (version !== undefined && version !== null && version !== this.version) {
      this.version = version;
      this.loadMap(version);
    }
    if (!this.fitted && !this.meta && this.state.pose) { this.fitted = true; this.reset(); }
    this.draw();
  }

  async loadMap(version) {
    try {
      const meta = await (await fetch("/api/map", { headers: { Accept: "application/json" } })).json();
      if (!meta) { this.meta = null; this.image = null; this.draw(); return; }
      const img = new Image();
      img.onload = () => {
        // Fitted to the view when the first map comes and when another map is chosen (a switch kept the last
        // map's zoom: a small map then sat tiny in a corner), not when the same map grows (mapping) or changes.
        const first = !this.meta || this.fittedMap !== this.state.active_map;
        this.meta = meta; this.image = img;
        if (first) { this.fittedMap = this.state.active_map; this.fitted = true; this.reset(); } else this.draw();
      };
      img.src = `/api/map.png?v=${encodeURIComponent(version)}`;
    } catch (err) {
      console.error("map", err);
    }
  }

  // -- drawing -----------------------------------------------------------------------------------
  draw() {
    const { ctx, canvas } = this;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#7f7f7f";
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    if (this.image && this.meta) {
      const m = this.meta;
      const [x0, y0] = this.toScreen(m.origin.x_m, m.origin.y_m + m.height_px * m.resolution_m);
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(this.image, x0, y0, m.width_px * m.resolution_m * this.scale, m.height_px * m.resolution_m * this.scale);
    } else {
      this.grid();
    }
    const s = this.state;
    this.path(s.global_path, "#1f6feb", 2);
    this.path(s.local_path, "#2da44e", 3);
    if (Array.isArray(s.depth_obstacles) && this.meta) {  // the depth camera's layer: one square per cell
      const side = Math.max(2, this.meta.resolution_m * this.scale);
      ctx.fillStyle = "rgba(219, 109, 40, 0.75)";
      for (const p of s.depth_obstacles) {
        const [sx, sy] = this.toScreen(p[0], p[1]);
        ctx.fillRect(sx - side / 2, sy - side / 2, side, side);
      }
    }
    if (Array.isArray(s.scan)) {
      ctx.fillStyle = "#e5534b";
      for (const p of s.scan) {
        const [sx, sy] = this.toScreen(p[0], p[1]);
        ctx.fillRect(sx - 1.5, sy - 1.5, 3, 3);
      }
    }
    if (Array.isArray(s.places)) for (const p of s.places) this.place(p);
    if (s.goal) this.arrow(s.goal, "#d4a72c", 0.35);
    const candidates = (s.localization && s.localization.candidates) || [];
    for (const c of candidates) this.arrow(c, "#bf8700", 0.45);  // places an ambiguous search cannot tell apart
    if (this.pending) this.arrow(this.pending, "#8250df", 0.5);
    if (s.pose) this.robot(s.pose);
    if (this.drag && this.drag.end && this.commandMode) {
      const [x, y] = this.drag.start;
      const yaw = Math.atan2(this.drag.end[1] - y, this.drag.end[0] - x);
      this.arrow({ x_m: x, y_m: y, yaw_rad: yaw }, "#8250df", 0.5);
    }
  }

  grid() {
    const { ctx, canvas } = this;
    ctx.strokeStyle = "#8c8c8c";
    ctx.lineWidth = 1;
    const [x0, y1] = this.toWorld(0, 0);
    const [x1, y0] = this.toWorld(canvas.width, canvas.height);
    for (let x = Math.floor(x0); x <= x1; x++) {
      const [sx] = this.toScreen(x, 0);
      ctx.beginPath(); ctx.moveTo(sx, 0); ctx.lineTo(sx, canvas.height); ctx.stroke();
    }
    for (let y = Math.floor(y0); y <= y1; y++) {
      const [, sy] = this.toScreen(0, y);
      ctx.beginPath(); ctx.moveTo(0, sy); ctx.lineTo(canvas.width, sy); ctx.stroke();
    }
  }

  path(points, color, width) {
    if (!Array.isArray(points) || points.length < 2) return;
    const { ctx } = this;
    ctx.strokeStyle = color; ctx.lineWidth = width;
    ctx.beginPath();
    points.forEach((p, i) => { const [sx, sy] = this.toScreen(p[0], p[1]); if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy); });
    ctx.stroke();
  }

  arrow(pose, color, length) {
    const { ctx } = this;
    const [sx, sy] = this.toScreen(pose.x_m, pose.y_m);
    const [ex, ey] = this.toScreen(pose.x_m + length * Math.cos(pose.yaw_rad), pose.y_m + length * Math.sin(pose.yaw_rad));
    ctx.strokeStyle = color; ctx.fillStyle = color; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.arc(sx, sy, 4, 0, 2 * Math.PI); ctx.fill();
    ctx.beginPath(); ctx.moveTo(sx, sy); ctx.lineTo(ex, ey); ctx.stroke();
  }

  place(p) {
    const { ctx } = this;
    this.arrow(p, p.kind === "dock" ? "#1a7f37" : "#bf3989", 0.3);
    const [sx, sy] = this.toScreen(p.x_m, p.y_m);
    ctx.font = `${Math.round(12 * (window.devicePixelRatio || 1))}px sans-serif`;
    ctx.lineWidth = 3; ctx.strokeStyle = "#fff"; ctx.fillStyle = "#24292f";
    ctx.strokeText(p.name, sx + 7, sy - 7); ctx.fillText(p.name, sx + 7, sy - 7);
  }

  robot(pose) {
    const { ctx } = this;
    const r = Math.max(6, 0.25 * this.scale);
    const [sx, sy] = this.toScreen(pose.x_m, pose.y_m);
    ctx.save();
    ctx.translate(sx, sy);
    ctx.rotate(-pose.yaw_rad);
    ctx.fillStyle = "rgba(31, 111, 235, 0.85)";
    ctx.strokeStyle = "#fff"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(r, 0); ctx.lineTo(-r * 0.7, r * 0.7); ctx.lineTo(-r * 0.7, -r * 0.7); ctx.closePath();
    ctx.fill(); ctx.stroke();
    ctx.restore();
  }
}

window.MapView = MapView;
