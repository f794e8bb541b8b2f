// What the 2D viewers share (laser.js, trail.js, map.js, navsat.js, cloud.js): a square canvas at the screen's
// pixels, drawn at an animation frame only when something new came (invalidate()), a view of metres (x right,
// y up, as ROS's top-down) fitted to a box, a grid with a scale bar, and a colour map.

// A canvas of the size its CSS box has (style.css: as wide as its place, square but no taller than the window
// leaves room for), at devicePixelRatio; paint(context, width, height) is called at the next animation frame after
// invalidate(), once per frame at most.
export class Plane {
  constructor(canvas, paint) {
    this.canvas = canvas;
    this.context = canvas.getContext('2d');
    this.paint = paint;
    this.frame = null;
    this.paints = 0;
    this.closed = false;
    this.sizer = new ResizeObserver(entries => {
      const box = entries[0].contentRect;
      const width = Math.max(1, Math.round(box.width * devicePixelRatio));
      const height = Math.max(1, Math.round(box.height * devicePixelRatio));
      if (width === canvas.width && height === canvas.height) return;
      canvas.width = width;
      canvas.height = height;
      this.invalidate();
    });
    this.sizer.observe(canvas);
  }

  invalidate() {
    if (this.frame !== null || this.closed) return;
    this.frame = requestAnimationFrame(() => {
      this.frame = null;
      if (!this.closed && this.canvas.isConnected) {
        this.paint(this.context, this.canvas.width, this.canvas.height);
        this.canvas.dataset.paints = String(++this.paints);  // (for whoever measures the page)
      }
    });
  }

  close() {
    this.closed = true;
    this.sizer.disconnect();
    if (this.frame !== null) cancelAnimationFrame(this.frame);
  }
}

// Metres -> canvas pixels: the box [minX, maxX] x [minY, maxY] fitted in width x height with a margin, y up.
export class View {
  constructor(box, width, height, margin = 0.06) {
    const [minX, maxX, minY, maxY] = box;
    const spanX = Math.max(maxX - minX, 1e-6);
    const spanY = Math.max(maxY - minY, 1e-6);
    this.scale = Math.min(width * (1 - 2 * margin) / spanX, height * (1 - 2 * margin) / spanY);  // px per metre
    this.cx = (minX + maxX) / 2;
    this.cy = (minY + maxY) / 2;
    this.width = width;
    this.height = height;
  }

  x(metres) {
    return this.width / 2 + (metres - this.cx) * this.scale;
  }

  y(metres) {
    return this.height / 2 - (metres - this.cy) * this.scale;
  }
}

// A box holding every point of xs, ys (finite ones), at least `least` metres wide, or null for none.
export function boxOf(xs, ys, least = 1) {
  let [minX, maxX, minY, maxY] = [Infinity, -Infinity, Infinity, -Infinity];
  for (let i = 0; i < xs.length; i++) {
    const x = xs[i];
    const y = ys[i];
    if (!Number.isFinite(x) || !Number.isFinite(y)) continue;
    if (x < minX) minX = x;
    if (x > maxX) maxX = x;
    if (y < minY) minY = y;
    if (y > maxY) maxY = y;
  }
  if (minX > maxX) return null;
  const grow = (low, high) => {
    const missing = Math.max(0, least - (high - low)) / 2;
    return [low - missing, high + missing];
  };
  return [...grow(minX, maxX), ...grow(minY, maxY)];
}

// 1, 2 or 5 times a power of ten, the first at least `value`.
export function niceStep(value) {
  const power = 10 ** Math.floor(Math.log10(Math.max(value, 1e-9)));
  return [1, 2, 5, 10].map(k => k * power).find(step => step >= value);
}

export function formatMetres(value) {
  const metres = value * (1 + 1e-6);  // (a float32 0.01 is 0.0099999998: 1 cm, not 10 mm)
  if (metres >= 1000) return `${+(metres / 1000).toFixed(2)} km`;
  if (metres >= 1) return `${+metres.toFixed(2)} m`;
  if (metres >= 0.01) return `${+(metres * 100).toFixed(1)} cm`;
  return `${+(metres * 1000).toFixed(1)} mm`;
}

// The background, a grid every nice step (about 60 CSS px apart) and a scale bar of one step, bottom left.
export function drawGrid(context, view) {
  const { width, height } = view;
  const ratio = devicePixelRatio;
  context.fillStyle = '#0f1424';
  context.fillRect(0, 0, width, height);
  const step = niceStep(60 * ratio / view.scale);
  context.strokeStyle = '#222c4a';
  context.lineWidth = 1;
  context.beginPath();
  const left = view.cx - width / 2 / view.scale;
  const bottom = view.cy - height / 2 / view.scale;
  for (let x = Math.ceil(left / step) * step; x <= left + width / view.scale; x += step) {
    context.moveTo(Math.round(view.x(x)) + 0.5, 0);
    context.lineTo(Math.round(view.x(x)) + 0.5, height);
  }
  for (let y = Math.ceil(bottom / step) * step; y <= bottom + height / view.scale; y += step) {
    context.moveTo(0, Math.round(view.y(y)) + 0.5);
    context.lineTo(width, Math.round(view.y(y)) + 0.5);
  }
  context.stroke();
  drawScale(context, view, step);
}

export function drawScale(context, view, step = niceStep(60 * devicePixelRatio / view.scale)) {
  const ratio = devicePixelRatio;
  const length = step * view.scale;
  const x0 = 10 * ratio;
  const y0 = view.height - 10 * ratio;
  context.fillStyle = 'rgba(15, 20, 36, 0.75)';  // (readable on a white map too)
  context.fillRect(x0 - 6 * ratio, y0 - 22 * ratio, length + 12 * ratio, 28 * ratio);
  context.strokeStyle = '#e8ecf8';
  context.lineWidth = 2 * ratio;
  context.beginPath();
  context.moveTo(x0, y0 - 5 * ratio);
  context.lineTo(x0, y0);
  context.lineTo(x0 + length, y0);
  context.lineTo(x0 + length, y0 - 5 * ratio);
  context.stroke();
  context.fillStyle = '#e8ecf8';
  context.font = `${12 * ratio}px system-ui, sans-serif`;
  context.textBaseline = 'bottom';
  context.fillText(formatMetres(step), x0 + 4 * ratio, y0 - 4 * ratio);
}

// An arrow at (px, py) canvas pixels pointing at `yaw` (radians, ROS's: counter-clockwise from x), `size` px.
export function drawArrow(context, px, py, yaw, size, colour) {
  const c = Math.cos(yaw);
  const s = -Math.sin(yaw);  // (canvas y down)
  const point = (forward, side) => [px + forward * c - side * s, py + forward * s + side * c];
  context.fillStyle = colour;
  context.strokeStyle = '#0f1424';
  context.lineWidth = Math.max(1, size / 10);
  context.beginPath();
  context.moveTo(...point(size, 0));
  context.lineTo(...point(-size * 0.6, size * 0.6));
  context.lineTo(...point(-size * 0.3, 0));
  context.lineTo(...point(-size * 0.6, -size * 0.6));
  context.closePath();
  context.fill();
  context.stroke();
}

// Turbo-like colours from blue (0) through green and yellow to red (1): [r, g, b].
const STOPS = [[48, 18, 59], [70, 134, 251], [27, 229, 181], [164, 252, 60], [251, 185, 56], [228, 70, 10],
  [122, 4, 3]];
export function colourAt(t) {
  const k = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (STOPS.length - 1);
  const i = Math.min(STOPS.length - 2, Math.floor(k));
  const f = k - i;
  return STOPS[i].map((a, j) => Math.round(a + (STOPS[i + 1][j] - a) * f));
}

// A colour key: a bar from colourAt(0) to colourAt(1) labelled low and high, top right.
export function drawColourKey(context, width, low, high) {
  const ratio = devicePixelRatio;
  const w = 90 * ratio;
  const h = 8 * ratio;
  const x0 = width - w - 10 * ratio;
  const y0 = 10 * ratio;
  for (let i = 0; i < w; i++) {
    context.fillStyle = `rgb(${colourAt(i / w).join(',')})`;
    context.fillRect(x0 + i, y0, 1.5, h);
  }
  context.fillStyle = '#e8ecf8';
  context.font = `${11 * ratio}px system-ui, sans-serif`;
  context.textBaseline = 'top';
  context.textAlign = 'left';
  context.fillText(low, x0, y0 + h + 2 * ratio);
  context.textAlign = 'right';
  context.fillText(high, x0 + w, y0 + h + 2 * ratio);
  context.textAlign = 'left';
}

// A ROS quaternion's yaw (rotation about z), radians.
export function yawOf(q) {
  if (!q) return 0;
  const { x = 0, y = 0, z = 0, w = 1 } = q;
  return Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
}

// A number array of a message: a typed array (CBOR) or a list (JSON, where NaN and infinities came as null).
export function numbers(values) {
  if (!values) return [];
  if (ArrayBuffer.isView(values)) return values;
  return values.map(v => (v === null ? NaN : v));
}
