// The turtle world drawn to scale like turtlesim's window (its size, background and pen from
// world-constants.js), origin bottom-left, y up. Trails are drawn from successive poses in the default pen colour
// (the pen colour is not published), on an offscreen "trail image" kept at the canvas's device-pixel resolution.
import WORLD from '../world-constants.js';

const WORLD_M = WORLD.size_m;
const WORLD_PX = WORLD.size_px;
const BACKGROUND = `rgb(${WORLD.background.join(', ')})`;
const PEN = `rgb(${WORLD.pen.join(', ')})`;
const MAX_SEGMENTS = 200000;  // oldest trail segments are forgotten beyond this
const REBORN_MS = 1000;  // after a reset, how long a pose of turtle1 away from the centre may be the old turtle's
// Shell colours; turtle1 gets the first. Chosen to stand out on the blue background and the pale pen.
const PALETTE = [[46, 204, 113], [255, 176, 32], [255, 99, 146], [38, 222, 235], [190, 140, 255], [240, 226, 70]];

export class WorldView {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.trail = document.createElement('canvas');
    this.trailCtx = this.trail.getContext('2d');
    this.turtles = new Map();  // name -> {pose, colour, joined: the next pose continues its trail}
    this.reborn = null;  // {name, until}: see forgetTurtles
    this.segments = [];  // [x0, y0, x1, y1] in metres, flat
    this.dirty = false;
    canvas.style.background = BACKGROUND;  // (until the first picture is drawn)
    this.sizer = new ResizeObserver(entries => this.resize(entries[0]));
    this.sizer.observe(canvas);
  }

  close() {
    this.sizer.disconnect();
  }

  // Device pixels per world pixel.
  get k() {
    return this.canvas.width / WORLD_PX;
  }

  // World metres -> canvas device pixels.
  toCanvas(x, y) {
    const s = this.k * WORLD_PX / WORLD_M;
    return [x * s, (WORLD_M - y) * s];
  }

  resize(entry) {
    const size = Math.max(1, Math.round(entry.contentRect.width * devicePixelRatio));
    if (size === this.canvas.width) return;
    this.canvas.width = this.canvas.height = this.trail.width = this.trail.height = size;
    this.redrawTrail();
  }

  setPose(name, pose) {
    const stale = this.isStale(name, pose);
    const turtle = this.turtles.get(name);
    if (!turtle) {
      this.turtles.set(name, { pose, colour: colourFor(name, this.turtles.size), joined: !stale });
    } else {
      const last = turtle.pose;
      if (turtle.joined && (last.x !== pose.x || last.y !== pose.y)) this.addSegment(last.x, last.y, pose.x, pose.y);
      turtle.pose = pose;
      turtle.joined = !stale;
    }
    this.invalidate();
  }

  // Whether a pose may be the old turtle's, from before a reset (see forgetTurtles): it is shown, and no trail
  // joins it.
  isStale(name, pose) {
    if (this.reborn?.name !== name) return false;
    const centre = WORLD_M / 2;
    if (performance.now() < this.reborn.until && Math.hypot(pose.x - centre, pose.y - centre) > 1e-3) return true;
    this.reborn = null;
    return false;
  }

  get names() {
    return [...this.turtles.keys()];
  }

  remove(name) {
    if (this.turtles.delete(name)) this.invalidate();
  }

  // While we cannot see the turtles (no connection) we do not know the path they take: their trails
  // resume from wherever they are next seen, instead of a made-up straight line.
  breakTrails() {
    for (const turtle of this.turtles.values()) turtle.joined = false;
  }

  // Like turtlesim's clear(): fills the trail image with the background; turtles stay.
  clearTrails() {
    this.segments = [];
    this.redrawTrail();
  }

  // After /reset the old turtles are gone: no line may join an old pose to the new turtle1. A pose the old
  // turtle1 published before the reset may still come after the service's answer (the topic and the service are
  // two connections): the new turtle1's trail starts where turtlesim puts it, the centre (or REBORN_MS later).
  forgetTurtles() {
    this.turtles.clear();
    this.clearTrails();
    this.reborn = { name: 'turtle1', until: performance.now() + REBORN_MS };
  }

  addSegment(x0, y0, x1, y1) {
    if (this.segments.length >= MAX_SEGMENTS * 4) this.segments.splice(0, MAX_SEGMENTS * 2);
    this.segments.push(x0, y0, x1, y1);
    this.strokeSegments(this.segments.length - 4);
  }

  redrawTrail() {
    const c = this.trailCtx;
    c.fillStyle = BACKGROUND;
    c.fillRect(0, 0, this.trail.width, this.trail.height);
    this.strokeSegments(0);
  }

  strokeSegments(from) {
    const c = this.trailCtx;
    c.strokeStyle = PEN;
    c.lineWidth = WORLD.pen_width_px * this.k;
    c.lineCap = 'round';
    c.beginPath();
    for (let i = from; i < this.segments.length; i += 4) {
      c.moveTo(...this.toCanvas(this.segments[i], this.segments[i + 1]));
      c.lineTo(...this.toCanvas(this.segments[i + 2], this.segments[i + 3]));
    }
    c.stroke();
    this.invalidate();
  }

  invalidate() {
    if (this.dirty) return;
    this.dirty = true;
    requestAnimationFrame(() => this.draw());
  }

  draw() {
    this.dirty = false;
    const c = this.ctx;
    c.drawImage(this.trail, 0, 0);
    for (const [name, { pose, colour }] of this.turtles) {
      if (!pose) continue;
      const [px, py] = this.toCanvas(pose.x, pose.y);
      drawTurtle(c, px, py, pose.theta, this.k * WORLD_PX / WORLD_M, colour);
      if (this.turtles.size > 1) drawLabel(c, name, px, py - 0.62 * this.k * WORLD_PX / WORLD_M, this.k);
    }
  }

  // A read-only view for tests and the curious: window.turtleView.
  debugHook() {
    const view = this;
    return Object.freeze({
      get poses() {
        return Object.fromEntries([...view.turtles].map(([n, t]) => [n, { ...t.pose }]));
      },
      colourOf: name => view.turtles.get(name)?.colour,
      toCanvas: (x, y) => view.toCanvas(x, y),
      get segmentCount() {
        return view.segments.length / 4;
      },
    });
  }
}

function colourFor(name, index) {
  const n = /^turtle(\d+)$/.exec(name);
  return PALETTE[(n ? Number(n[1]) - 1 : index) % PALETTE.length];
}

// A turtle seen from above, about 1 m long like turtlesim's sprites, nose towards theta.
// m = device pixels per metre.
function drawTurtle(c, x, y, theta, m, [r, g, b]) {
  const shell = `rgb(${r}, ${g}, ${b})`;
  const dark = `rgb(${r * 0.45 | 0}, ${g * 0.45 | 0}, ${b * 0.45 | 0})`;
  c.save();
  c.translate(x, y);
  c.rotate(-theta);  // canvas y points down, world y up
  c.scale(m, m);
  c.lineWidth = 0.045;
  c.strokeStyle = dark;
  c.fillStyle = dark;
  for (const [lx, ly] of [[0.2, 0.27], [0.2, -0.27], [-0.2, 0.25], [-0.2, -0.25]]) {
    c.beginPath();
    c.ellipse(lx, ly, 0.1, 0.065, Math.sign(lx * ly) * 0.6, 0, 2 * Math.PI);
    c.fill();
  }
  c.beginPath();  // tail
  c.moveTo(-0.3, 0.06);
  c.lineTo(-0.44, 0);
  c.lineTo(-0.3, -0.06);
  c.fill();
  c.beginPath();  // head
  c.ellipse(0.4, 0, 0.14, 0.115, 0, 0, 2 * Math.PI);
  c.fillStyle = shell;
  c.fill();
  c.stroke();
  c.beginPath();  // shell
  c.ellipse(0, 0, 0.33, 0.27, 0, 0, 2 * Math.PI);
  c.fill();
  c.stroke();
  c.beginPath();  // shell plates
  c.moveTo(0.15, 0);
  for (let i = 1; i <= 6; i++) c.lineTo(0.15 * Math.cos(i * Math.PI / 3), 0.13 * Math.sin(i * Math.PI / 3));
  c.stroke();
  c.fillStyle = '#10131f';  // eyes: they make the nose unmistakable
  for (const ey of [0.055, -0.055]) {
    c.beginPath();
    c.arc(0.46, ey, 0.028, 0, 2 * Math.PI);
    c.fill();
  }
  c.restore();
}

function drawLabel(c, text, x, y, k) {
  c.save();
  c.font = `600 ${Math.round(12 * k)}px system-ui, sans-serif`;
  c.textAlign = 'center';
  c.textBaseline = 'bottom';
  c.lineWidth = 3 * k;
  c.strokeStyle = 'rgba(16, 19, 31, 0.75)';
  c.strokeText(text, x, y);
  c.fillStyle = '#fff';
  c.fillText(text, x, y);
  c.restore();
}
