// sensor_msgs/LaserScan: the points around the sensor (at the centre, x right, y up, as seen from above), each
// coloured by its range from the nearest to the farthest (a key, top right), rings every nice distance and a scale bar; invalid ranges (NaN, below
// range_min, beyond range_max, infinite: no return) are left out and counted. Binary CBOR (the ranges a
// Float32Array), at most one scan per animation frame; drawn only when a new one came.
import { Plane, colourAt, drawColourKey, drawScale, formatMetres, niceStep, numbers } from './plane.js';

const FRAME_MS = 16;  // at most one message per animation frame (60 Hz): a 40 Hz topic is drawn at 40 Hz

export class LaserScanViewer {
  static subscription = { compression: 'cbor', throttle_rate: FRAME_MS, queue_length: 1 };

  constructor(element) {
    element.innerHTML = '<canvas class="plane" role="img" aria-label="The laser scan from above"></canvas>' +
      '<p class="viewer-stats" aria-live="off">waiting for a scan…</p>';
    this.stats = element.querySelector('.viewer-stats');
    this.plane = new Plane(element.querySelector('canvas'), (context, width, height) => this.paint(context, width,
      height));
    this.scan = null;
    this.received = 0;
    this.reach = 0;  // the radius shown (m): grows at once, shrinks slowly (no jumping scale)
  }

  draw(scan) {
    this.scan = scan;
    this.plane.canvas.dataset.received = String(++this.received);  // (for whoever measures the page)
    this.plane.invalidate();
  }

  paint(context, width, height) {
    const ratio = devicePixelRatio;
    context.fillStyle = '#0f1424';
    context.fillRect(0, 0, width, height);
    const scan = this.scan;
    if (!scan) return;
    const ranges = numbers(scan.ranges);
    const low = Number.isFinite(scan.range_min) ? scan.range_min : 0;
    const high = Number.isFinite(scan.range_max) && scan.range_max > 0 ? scan.range_max : Infinity;
    let far = 0;
    let near = Infinity;
    let valid = 0;
    for (let i = 0; i < ranges.length; i++) {
      const r = ranges[i];
      if (r >= low && r <= high) {  // (false for NaN)
        valid++;
        if (r > far) far = r;
        if (r < near) near = r;
      }
    }
    const wanted = Math.max(far, 0.5) * 1.05;
    this.reach = wanted > this.reach || wanted < this.reach * 0.7 ? wanted : this.reach;
    const scale = Math.min(width, height) / 2 / this.reach;  // px per metre
    const cx = width / 2;
    const cy = height / 2;
    // rings
    const step = niceStep(this.reach / 5);
    context.strokeStyle = '#26305a';
    context.lineWidth = ratio;
    context.fillStyle = '#7f8bb0';
    context.font = `${11 * ratio}px system-ui, sans-serif`;
    context.textBaseline = 'bottom';
    for (let r = step; r <= this.reach * 1.5; r += step) {
      context.beginPath();
      context.arc(cx, cy, r * scale, 0, 2 * Math.PI);
      context.stroke();
      context.fillText(formatMetres(r), cx + 3 * ratio, cy - r * scale - 2 * ratio);
    }
    context.beginPath();
    context.moveTo(cx - 6 * ratio, cy);
    context.lineTo(cx + 14 * ratio, cy);  // the sensor's x axis
    context.moveTo(cx, cy - 6 * ratio);
    context.lineTo(cx, cy + 6 * ratio);
    context.strokeStyle = '#e8ecf8';
    context.stroke();
    // points, coloured by range
    const size = Math.max(2, Math.round(2 * ratio));
    const span = Math.max(far - near, 1e-6);  // colours from the nearest point to the farthest
    const angleMin = scan.angle_min ?? 0;
    const increment = scan.angle_increment ?? 0;
    const buckets = 16;  // one fillStyle per colour bucket (a scan is 1000+ points at 40 Hz)
    const paths = Array.from({ length: buckets }, () => new Path2D());
    for (let i = 0; i < ranges.length; i++) {
      const r = ranges[i];
      if (!(r >= low && r <= high)) continue;
      const angle = angleMin + i * increment;
      const x = cx + r * Math.cos(angle) * scale;
      const y = cy - r * Math.sin(angle) * scale;
      paths[Math.min(buckets - 1, Math.floor((r - near) / span * buckets))].rect(x - size / 2, y - size / 2, size, size);
    }
    paths.forEach((path, b) => {
      context.fillStyle = `rgb(${colourAt((b + 0.5) / buckets).join(',')})`;
      context.fill(path);
    });
    drawScale(context, { scale, height, width }, step);
    if (valid) drawColourKey(context, width, formatMetres(near), formatMetres(far));
    const text = `${ranges.length} rays · ${valid} in range · ${valid ? `${formatMetres(near)} to ${formatMetres(far)}` :
      'none'} · ` +
      `frame ${scan.header?.frame_id || '—'}`;
    if (this.stats.textContent !== text) this.stats.textContent = text;
    this.plane.canvas.dataset.points = String(valid);
  }

  close() {
    this.plane.close();
  }
}
