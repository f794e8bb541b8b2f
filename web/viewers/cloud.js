// sensor_msgs/PointCloud2 from above (x right, y up), coloured by height (z; else intensity), with a scale bar
// and a colour key. The points do not come over the websocket: the bridge decimates each cloud to at most
// MAX_POINTS (GET /cloud, cloud_pages.py on the bridge) and the page asks for the next one only once it has drawn
// the last (after=seq: the bridge answers when a newer cloud comes), so clouds come at the topic's rate, never
// faster than they are drawn, and a 300k-point cloud costs the link 12 bytes per point kept.
import { Plane, View, boxOf, colourAt, drawColourKey, drawGrid, formatMetres } from './plane.js';
import { formatBytes } from '../format.js';

const MAX_POINTS = 20000;
const RETRY_MS = 1000;

export class PointCloudViewer {
  // The host's own subscription (its tree) takes one cloud in 30 s, binary: the points come by /cloud, and a
  // whole 300k-point cloud is 4.8 MB (once a second that would be 5 MB/s to a phone). Its rate and age lines are
  // the drawing's (onDrawn).
  static subscription = { compression: 'cbor', throttle_rate: 30000, queue_length: 1 };

  // onDrawn (registry.js): each cloud drawn, so that its topic's rate and age lines tell the drawing's.
  constructor(element, { topic, onDrawn = () => {} }) {
    this.topic = topic;
    this.onDrawn = onDrawn;
    element.innerHTML = '<canvas class="plane" role="img" aria-label="The point cloud from above"></canvas>' +
      '<p class="viewer-stats" aria-live="off">waiting for a cloud…</p>';
    this.stats = element.querySelector('.viewer-stats');
    this.plane = new Plane(element.querySelector('canvas'), (context, width, height) => this.paint(context, width,
      height));
    this.cloud = null;  // { points: Float32Array of triples, kept, total, third, frame, bytes, stamp (s) or null }
    this.seq = 0;
    this.asked = null;  // the AbortController of the request in flight
    this.session = null;
    this.problem = null;
    this.drawnOnce = null;  // resolves when the cloud taken is drawn
  }

  attach(session) {
    this.detach();
    this.session = session;
    this.fetchLoop(session);
  }

  detach() {
    this.asked?.abort();
    this.asked = null;
    this.session = null;
  }

  draw() {}  // (the points come by /cloud)

  async fetchLoop(session) {
    while (this.session === session && !session.closed) {
      const asked = this.asked = new AbortController();
      const url = new URL('cloud', session.http);
      for (const [key, value] of Object.entries({ topic: this.topic, max_points: MAX_POINTS, after: this.seq })) {
        url.searchParams.set(key, value);
      }
      try {
        const answer = await fetch(url, { signal: asked.signal, cache: 'no-store' });
        if (answer.status === 204) continue;  // nothing newer yet
        if (!answer.ok) throw new Error(`${answer.status} ${(await answer.text()).trim().slice(0, 200)}`);
        const buffer = await answer.arrayBuffer();
        session.received += buffer.byteLength;
        const header = name => answer.headers.get(name);
        this.seq = Number(header('x-seq')) || this.seq + 1;
        this.cloud = { points: new Float32Array(buffer), kept: Number(header('x-points')),
          total: Number(header('x-points-total')), third: header('x-third') || 'none',
          frame: frameId(header('x-frame-id') || ''), bytes: buffer.byteLength,
          stamp: Number.parseFloat(header('x-timestamp')) || null };
        this.problem = null;
        await new Promise(resolve => {  // the next one once this one is drawn
          this.drawnOnce = resolve;
          this.plane.invalidate();
        });
      } catch (error) {
        if (asked.signal.aborted || this.session !== session) return;
        this.problem = `The cloud could not be read from the bridge (${error.message}); asking again.`;
        this.stats.textContent = this.problem;
        await new Promise(resolve => setTimeout(resolve, RETRY_MS));
      }
    }
  }

  paint(context, width, height) {
    const done = this.drawnOnce;
    this.drawnOnce = null;
    const cloud = this.cloud;
    const points = cloud?.points ?? new Float32Array(0);
    const n = Math.floor(points.length / 3);
    const xs = new Float32Array(n);
    const ys = new Float32Array(n);
    let low = Infinity;
    let high = -Infinity;
    for (let i = 0; i < n; i++) {
      xs[i] = points[3 * i];
      ys[i] = points[3 * i + 1];
      const v = points[3 * i + 2];
      if (Number.isFinite(v) && Number.isFinite(xs[i]) && Number.isFinite(ys[i])) {
        if (v < low) low = v;
        if (v > high) high = v;
      }
    }
    const view = new View(boxOf(xs, ys, 1) ?? [-5, 5, -5, 5], width, height, 0.05);
    drawGrid(context, view);
    const image = context.getImageData(0, 0, width, height);
    const pixels = new Uint32Array(image.data.buffer);
    const palette = new Uint32Array(64);
    for (let k = 0; k < 64; k++) {
      const [r, g, b] = colourAt(k / 63);
      palette[k] = 0xff000000 | (b << 16) | (g << 8) | r;
    }
    const span = high > low ? high - low : 1;
    const size = Math.max(1, Math.round(devicePixelRatio * 1.5));
    let shown = 0;
    for (let i = 0; i < n; i++) {
      const px = Math.round(view.x(xs[i]));
      const py = Math.round(view.y(ys[i]));
      if (!(px >= 0 && py >= 0 && px < width - size && py < height - size)) continue;  // (NaN too)
      const v = points[3 * i + 2];
      const colour = palette[Number.isFinite(v) ? Math.round((v - low) / span * 63) : 0];
      for (let dy = 0; dy < size; dy++) pixels.fill(colour, (py + dy) * width + px, (py + dy) * width + px + size);
      shown++;
    }
    context.putImageData(image, 0, 0);
    if (cloud && cloud.third !== 'none' && low <= high) {
      const unit = cloud.third === 'z' ? ' m' : '';
      drawColourKey(context, width, `${cloud.third} ${+low.toFixed(2)}${unit}`, `${+high.toFixed(2)}${unit}`);
    }
    this.plane.canvas.dataset.points = String(shown);
    if (cloud) {
      const text = `${cloud.kept} of ${cloud.total} points (decimated on the bridge) · ${shown} shown · ` +
        `${formatBytes(cloud.bytes)} · coloured by ${cloud.third} · frame ${cloud.frame || '—'} · ` +
        `${formatMetres((view.width / view.scale))} across`;
      if (!this.problem && this.stats.textContent !== text) this.stats.textContent = text;
    }
    if (done && cloud) {
      this.onDrawn({ stamp: cloud.stamp, bytes: cloud.bytes, noun: 'cloud', via: 'fetched by /cloud' });
    }
    done?.();
  }

  close() {
    this.detach();
    this.plane.close();
    this.drawnOnce?.();
  }
}

// X-Frame-Id is the frame id percent-encoded (its UTF-8), so that any frame id fits in a header.
function frameId(text) {
  try {
    return decodeURIComponent(text);
  } catch {
    return text;  // (not percent-encoded: a bridge from before it was)
  }
}
