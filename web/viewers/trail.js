// nav_msgs/Odometry, geometry_msgs/PoseStamped, nav_msgs/Path: the trail in the messages' frame from above (x
// right, y up), fitted to the canvas with a grid and a scale bar, the newest pose as an arrow (its heading), and
// the speed: the odometry's twist, else from the last poses (their stamps, or their arrival). A Path is drawn as
// it is (the trail is its poses). At most one message per animation frame (throttled by the bridge); drawn only
// when one came.
import { Plane, View, boxOf, drawArrow, drawGrid, formatMetres, yawOf } from './plane.js';

const FRAME_MS = 16;  // at most one message per animation frame (60 Hz): a 40 Hz topic is drawn at 40 Hz

const MAX_POINTS = 20000;  // of a trail (the oldest forgotten)
const MIN_STEP_M = 0.005;  // a pose closer than this to the previous one adds nothing to the trail
const SPEED_WINDOW_S = 0.5;

export class TrailViewer {
  static subscription = { throttle_rate: FRAME_MS, queue_length: 1 };

  constructor(element, { type }) {
    this.type = type;
    element.innerHTML = '<canvas class="plane" role="img" aria-label="The trail from above"></canvas>' +
      '<p class="viewer-stats" aria-live="off">waiting for a pose…</p>';
    this.stats = element.querySelector('.viewer-stats');
    this.plane = new Plane(element.querySelector('canvas'), (context, width, height) => this.paint(context, width,
      height));
    this.xs = [];
    this.ys = [];
    this.recent = [];  // [t s, x, y] of the last SPEED_WINDOW_S, for a speed without a twist
    this.pose = null;  // { x, y, yaw }
    this.speed = null;  // m/s
    this.turn = null;  // rad/s (odometry only)
    this.frame = '';
    this.count = 0;
  }

  draw(message) {
    this.count++;
    if (this.type === 'nav_msgs/Path') {
      const poses = message.poses ?? [];
      this.xs = poses.map(p => p.pose?.position?.x ?? NaN);
      this.ys = poses.map(p => p.pose?.position?.y ?? NaN);
      const last = poses.at(-1)?.pose;
      this.pose = last ? { x: last.position.x, y: last.position.y, yaw: yawOf(last.orientation) } : null;
      this.speed = null;
      this.frame = message.header?.frame_id ?? '';
      this.plane.invalidate();
      return;
    }
    const pose = this.type === 'nav_msgs/Odometry' ? message.pose?.pose : message.pose;
    if (!pose?.position) return;
    const { x, y } = pose.position;
    if (!Number.isFinite(x) || !Number.isFinite(y)) return;
    this.frame = message.header?.frame_id ?? '';
    this.pose = { x, y, yaw: yawOf(pose.orientation) };
    const n = this.xs.length;
    if (!n || Math.hypot(x - this.xs[n - 1], y - this.ys[n - 1]) >= MIN_STEP_M) {
      this.xs.push(x);
      this.ys.push(y);
      if (this.xs.length > MAX_POINTS) {
        this.xs.splice(0, this.xs.length - MAX_POINTS);
        this.ys.splice(0, this.ys.length - MAX_POINTS);
      }
    }
    if (this.type === 'nav_msgs/Odometry') {
      const twist = message.twist?.twist;
      this.speed = Math.hypot(twist?.linear?.x ?? 0, twist?.linear?.y ?? 0);
      this.turn = twist?.angular?.z ?? 0;
    } else {
      const stamp = message.header?.stamp;
      const t = stamp && stamp.secs ? stamp.secs + stamp.nsecs / 1e9 : performance.now() / 1000;
      this.recent.push([t, x, y]);
      while (this.recent.length > 2 && this.recent[0][0] < t - SPEED_WINDOW_S) this.recent.shift();
      const [t0, x0, y0] = this.recent[0];
      this.speed = t > t0 ? Math.hypot(x - x0, y - y0) / (t - t0) : this.speed;
    }
    this.plane.invalidate();
  }

  paint(context, width, height) {
    const box = boxOf(this.xs, this.ys, 2) ?? [-1, 1, -1, 1];
    const view = new View(box, width, height, 0.1);
    drawGrid(context, view);
    const ratio = devicePixelRatio;
    context.strokeStyle = '#3fd68c';
    context.lineWidth = 2 * ratio;
    context.lineJoin = 'round';
    context.beginPath();
    let drawing = false;
    for (let i = 0; i < this.xs.length; i++) {
      const [x, y] = [this.xs[i], this.ys[i]];
      if (!Number.isFinite(x) || !Number.isFinite(y)) {
        drawing = false;
        continue;
      }
      if (drawing) context.lineTo(view.x(x), view.y(y));
      else context.moveTo(view.x(x), view.y(y));
      drawing = true;
    }
    context.stroke();
    if (this.pose) drawArrow(context, view.x(this.pose.x), view.y(this.pose.y), this.pose.yaw, 12 * ratio, '#ffc247');
    const parts = [];
    if (this.pose) {
      parts.push(`(${this.pose.x.toFixed(2)}, ${this.pose.y.toFixed(2)}) m`,
        `heading ${(this.pose.yaw * 180 / Math.PI).toFixed(0)}°`);
    }
    if (this.speed !== null) parts.push(`speed ${this.speed.toFixed(2)} m/s`);
    if (this.turn !== null) parts.push(`turn ${this.turn.toFixed(2)} rad/s`);
    parts.push(this.type === 'nav_msgs/Path' ? `${this.xs.length} poses` : `trail ${formatMetres(length(this))}`);
    if (this.frame) parts.push(`frame ${this.frame}`);
    const text = parts.join(' · ');
    if (this.stats.textContent !== text) this.stats.textContent = text;
  }

  close() {
    this.plane.close();
  }
}

function length({ xs, ys }) {
  let sum = 0;
  for (let i = 1; i < xs.length; i++) {
    const d = Math.hypot(xs[i] - xs[i - 1], ys[i] - ys[i - 1]);
    if (Number.isFinite(d)) sum += d;
  }
  return sum;
}
