// Camera: a live picture from a sensor_msgs/CompressedImage (jpeg or png, decoded by the browser) or a
// sensor_msgs/Image (rgb8, bgr8, mono8, 16UC1 depth as grey), carried as binary CBOR frames. The bridge sends
// the newest frame only once the page has read the last (throttle_rate with queue_length 1), so the picture
// never lags behind on a slow link; the panel shows frames per second and the age of the frame.
import { Panel, fillSelect } from './panel.js';

const IMAGE_TYPES = ['sensor_msgs/CompressedImage', 'sensor_msgs/Image'];
const FRAME_MS = 33;  // at most ~30 frames per second to this page
const STATS_MS = 1000;

export class CameraPanel extends Panel {
  constructor(root) {
    super(root, 'Could not list topics');
    this.select = root.querySelector('select.camera-topic');
    this.canvas = root.querySelector('canvas.camera');
    this.stats = root.querySelector('.camera-stats');
    this.subscription = null;
    this.types = new Map();
    this.frames = [];  // arrival times, last second
    this.age = null;
    this.select.addEventListener('change', () => this.watch(this.select.value));
    setInterval(() => this.showStats(), STATS_MS);
  }

  detach() {
    super.detach();
    this.subscription = null;  // (gone with the socket)
    this.shown = null;  // so that the next session watches the chosen camera again
  }

  async load(session) {
    const { topics, types } = await session.rosapi('topics');
    return topics.map((name, i) => [name, types[i]]).filter(([, type]) => IMAGE_TYPES.includes(type))
      .sort(([a], [b]) => a.localeCompare(b));
  }

  render(cameras) {
    this.types = new Map(cameras);
    fillSelect(this.select, cameras.length ? 'Choose a camera…' : 'No image topics',
      cameras.map(([name, type]) => [name, `${name} (${type.split('/')[1]})`]));
    if (this.select.value && !this.subscription) this.watch(this.select.value);
  }

  watch(topic) {
    this.subscription?.close();
    this.subscription = null;
    this.frames = [];
    if (!topic || !this.session) return;
    const type = this.types.get(topic);
    this.subscription = this.session.subscribe(topic, type, message => this.draw(type, message),
      { compression: 'cbor', throttle_rate: FRAME_MS, queue_length: 1 });
  }

  async draw(type, message) {
    this.frames.push(performance.now());
    const stamp = message.header?.stamp;
    this.age = ageOf(stamp);
    try {
      const picture = type === 'sensor_msgs/CompressedImage' ? await decodeCompressed(message) : decodeRaw(message);
      this.canvas.width = picture.width;
      this.canvas.height = picture.height;
      const context = this.canvas.getContext('2d');
      if (picture instanceof ImageData) context.putImageData(picture, 0, 0);
      else context.drawImage(picture, 0, 0);
      this.status.textContent = '';
      // Each frame drawn, with its age then, for whoever measures the page.
      this.canvas.dispatchEvent(new CustomEvent('frame', { detail: { age: ageOf(stamp) } }));
    } catch (error) {
      this.status.textContent = error.message;
    }
  }

  showStats() {
    const now = performance.now();
    this.frames = this.frames.filter(t => t > now - 1000);
    if (!this.subscription) {
      this.stats.textContent = '';
      return;
    }
    const age = this.age === null ? '' : ` · frame age ${(this.age * 1000).toFixed(0)} ms`;
    this.stats.textContent = `${this.frames.length} fps${age}`;
  }
}

// Seconds since a header stamp (null without one).
function ageOf(stamp) {
  return stamp && stamp.secs ? Date.now() / 1000 - (stamp.secs + stamp.nsecs / 1e9) : null;
}

function bytes(data) {
  return data instanceof Uint8Array ? data : Uint8Array.from(atob(data), c => c.charCodeAt(0));
}

function decodeCompressed(message) {
  const format = (message.format || 'jpeg').toLowerCase();
  const mime = format.includes('png') ? 'image/png' : 'image/jpeg';
  return createImageBitmap(new Blob([bytes(message.data)], { type: mime }));
}

function decodeRaw({ width, height, encoding, step, is_bigendian: bigEndian, data }) {
  const source = bytes(data);
  const image = new ImageData(width, height);
  const out = image.data;
  const pixel = {
    rgb8: (row, x) => [source[row + 3 * x], source[row + 3 * x + 1], source[row + 3 * x + 2]],
    bgr8: (row, x) => [source[row + 3 * x + 2], source[row + 3 * x + 1], source[row + 3 * x]],
    mono8: (row, x) => [source[row + x], source[row + x], source[row + x]],
    '16UC1': (row, x) => {  // depth in mm: 0..~8 m as black..white
      const i = row + 2 * x;
      const mm = bigEndian ? (source[i] << 8) | source[i + 1] : source[i] | (source[i + 1] << 8);
      const grey = Math.min(255, mm / 32);
      return [grey, grey, grey];
    },
  }[encoding];
  if (!pixel) throw new Error(`Image encoding ${encoding} is not shown (rgb8, bgr8, mono8, 16UC1 are).`);
  for (let y = 0; y < height; y++) {
    for (let x = 0; x < width; x++) {
      const [r, g, b] = pixel(y * step, x);
      const o = 4 * (y * width + x);
      out[o] = r;
      out[o + 1] = g;
      out[o + 2] = b;
      out[o + 3] = 255;
    }
  }
  return image;
}
