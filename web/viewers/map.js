// nav_msgs/OccupancyGrid: the map (unknown grey, free white, occupied black, shades between) made once per map
// into an offscreen canvas from its int8 cells (an Int8Array by binary CBOR; a 4000x4000 map is one loop over
// 16 M cells into a Uint32Array over the ImageData), drawn fitted to the canvas with a scale bar; and the robot
// placed by TF (../tf-store.js, shared with the TF viewer) when a transform from the map's frame to a robot frame
// exists: the frame chosen, by default base_footprint or base_link, else the first moving frame below the map's.
import { TfStore } from '../tf-store.js';
import { apply, transformOf } from '../tf-math.js';
import { Plane, View, drawArrow, drawScale, formatMetres, yawOf } from './plane.js';

const ROBOT_MS = 100;  // the robot's place is looked at this often (TF comes at up to 100 Hz)
const AUTO = '';  // the robot frame chosen by itself
const ROBOT_NAMES = ['base_footprint', 'base_link'];

export class OccupancyGridViewer {
  // Maps are big (a 4000x4000 one is 16 MB) and change slowly: binary CBOR, the newest only, one a second at most.
  static subscription = { compression: 'cbor', throttle_rate: 1000, queue_length: 1 };

  constructor(element) {
    element.innerHTML = `<label class="row map-robot">Robot frame <select aria-label="Robot frame">
        <option value="">automatic</option></select></label>
      <canvas class="plane" role="img" aria-label="The map"></canvas>
      <p class="viewer-stats" aria-live="off">waiting for a map…</p>`;
    this.select = element.querySelector('select');
    this.select.addEventListener('change', () => this.plane.invalidate());
    this.stats = element.querySelector('.viewer-stats');
    this.plane = new Plane(element.querySelector('canvas'), (context, width, height) => this.paint(context, width,
      height));
    this.image = document.createElement('canvas');  // the map at one pixel per cell
    this.info = null;  // the map's info, frame and origin transform
    this.robot = null;  // { frame, x, y, yaw } in the map's frame
    this.held = null;
    this.frames = '';
    this.timer = setInterval(() => this.placeRobot(), ROBOT_MS);
  }

  attach(session) {
    this.detach();
    this.held = TfStore.use(session);
  }

  detach() {
    this.held?.release();
    this.held = null;
  }

  draw(map) {
    const { width, height, resolution } = map.info ?? {};
    if (!(width > 0 && height > 0 && resolution > 0)) {
      this.info = null;
      this.stats.textContent = 'an empty map';
      this.plane.invalidate();
      return;
    }
    const cells = map.data ?? [];
    const image = new ImageData(width, height);
    const pixels = new Uint32Array(image.data.buffer);
    // little-endian RGBA as one number: 0xAABBGGRR
    const UNKNOWN = 0xff5a4e44;  // (68, 78, 90)
    const count = Math.min(cells.length, width * height);
    const shades = new Uint32Array(101);
    for (let v = 0; v <= 100; v++) {
      const g = Math.round(255 - v * 2.55);
      shades[v] = 0xff000000 | (g << 16) | (g << 8) | g;
    }
    // row 0 of the map is its bottom (y up): written bottom-up into the picture
    for (let row = 0; row < height; row++) {
      const out = (height - 1 - row) * width;
      const start = row * width;
      const end = Math.min(start + width, count);
      for (let i = start; i < end; i++) {
        const v = cells[i];
        pixels[out + i - start] = v >= 0 && v <= 100 ? shades[v] : UNKNOWN;
      }
      for (let i = Math.max(start, end); i < start + width; i++) pixels[out + i - start] = UNKNOWN;
    }
    this.image.width = width;
    this.image.height = height;
    this.image.getContext('2d').putImageData(image, 0, 0);
    let occupied = 0;
    let free = 0;
    for (let i = 0; i < count; i++) {
      const v = cells[i];
      if (v > 50) occupied++;
      else if (v >= 0) free++;
    }
    this.info = { width, height, resolution, frame: (map.header?.frame_id ?? '').replace(/^\/+/, ''),
      origin: transformOf({ translation: map.info.origin?.position, rotation: map.info.origin?.orientation }),
      occupied, free, unknown: width * height - occupied - free };
    this.placeRobot();
    this.plane.invalidate();
  }

  // The robot's pose in the map's frame, from TF.
  placeRobot() {
    const store = this.held?.store;
    if (!store || !this.info) return;
    const names = store.descendants(this.info.frame).filter(n => !store.frames.get(n).isStatic);
    const all = store.descendants(this.info.frame);
    if (all.join('\n') !== this.frames) {
      this.frames = all.join('\n');
      const chosen = this.select.value;
      this.select.replaceChildren(new Option('automatic', AUTO), ...all.map(n => new Option(n, n)));
      this.select.value = all.includes(chosen) ? chosen : AUTO;
    }
    const frame = this.select.value || ROBOT_NAMES.find(n => all.includes(n)) || names[0];
    const found = frame ? store.lookup(this.info.frame, frame) : null;
    const robot = found ? { frame, x: found.translation.x, y: found.translation.y, yaw: yawOf(found.rotation) } : null;
    if (JSON.stringify(robot) !== JSON.stringify(this.robot)) {
      this.robot = robot;
      this.plane.invalidate();
    }
  }

  paint(context, width, height) {
    context.fillStyle = '#0f1424';
    context.fillRect(0, 0, width, height);
    const info = this.info;
    if (!info) return;
    // the map's corners in its frame (its origin may be turned)
    const corners = [[0, 0], [info.width, 0], [0, info.height], [info.width, info.height]].map(([i, j]) =>
      apply(info.origin, { x: i * info.resolution, y: j * info.resolution, z: 0 }));
    const xs = corners.map(c => c.x);
    const ys = corners.map(c => c.y);
    const view = new View([Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)], width, height, 0.02);
    // cell (i, j) -> canvas: origin, then the metres view (y flipped); the picture is bottom-up already
    const yaw = yawOf(info.origin.rotation);
    context.save();
    context.translate(view.x(info.origin.translation.x), view.y(info.origin.translation.y));
    context.rotate(-yaw);
    context.imageSmoothingEnabled = info.resolution * view.scale < 2;
    const size = info.resolution * view.scale;
    context.drawImage(this.image, 0, -info.height * size, info.width * size, info.height * size);
    context.restore();
    drawScale(context, view);
    const robot = this.robot;
    if (robot) {
      const ratio = devicePixelRatio;
      drawArrow(context, view.x(robot.x), view.y(robot.y), robot.yaw, 11 * ratio, '#ff6b7d');
    }
    const where = robot ? `robot ${robot.frame} at (${robot.x.toFixed(2)}, ${robot.y.toFixed(2)}) m` :
      `no transform from ${info.frame || 'the map'} to a robot frame`;
    const text = `${info.width}×${info.height} cells of ${formatMetres(info.resolution)} · ` +
      `${info.occupied} occupied · ${info.free} free · ${info.unknown} unknown · ${where}`;
    if (this.stats.textContent !== text) this.stats.textContent = text;
  }

  close() {
    clearInterval(this.timer);
    this.plane.close();
    this.detach();
  }
}
