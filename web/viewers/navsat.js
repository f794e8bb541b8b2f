// sensor_msgs/NavSatFix: the fix's status and service, latitude, longitude, altitude and horizontal accuracy, and
// the track in metres east and north of the first fix (a local ENU plane: no map tiles, it works offline), the
// newest fix ringed by its accuracy. Fixes with status NO_FIX or without numbers are counted, not drawn.
import { Plane, View, boxOf, drawGrid, formatMetres } from './plane.js';

const EARTH_M = 6378137;  // WGS 84's equatorial radius
const STATUS = { '-1': 'no fix', 0: 'fix', 1: 'fix with satellite augmentation (SBAS)', 2: 'fix with ground augmentation (GBAS)' };
const SERVICES = [[1, 'GPS'], [2, 'GLONASS'], [4, 'Compass'], [8, 'Galileo']];
const MAX_POINTS = 20000;

export class NavSatFixViewer {
  static subscription = { throttle_rate: 100, queue_length: 1 };

  constructor(element) {
    element.innerHTML = '<p class="navsat-status" aria-live="off">waiting for a fix…</p>' +
      '<canvas class="plane" role="img" aria-label="The track in metres east and north of the first fix"></canvas>' +
      '<p class="viewer-stats" aria-live="off"></p>';
    this.status = element.querySelector('.navsat-status');
    this.stats = element.querySelector('.viewer-stats');
    this.plane = new Plane(element.querySelector('canvas'), (context, width, height) => this.paint(context, width,
      height));
    this.first = null;  // { lat, lon, alt }
    this.east = [];
    this.north = [];
    this.fix = null;
    this.noFix = 0;
  }

  draw(fix) {
    this.fix = fix;
    const status = fix.status?.status ?? -1;
    const { latitude: lat, longitude: lon } = fix;
    if (status >= 0 && Number.isFinite(lat) && Number.isFinite(lon)) {
      if (!this.first) this.first = { lat, lon };
      const rad = Math.PI / 180;
      this.east.push((lon - this.first.lon) * rad * EARTH_M * Math.cos(this.first.lat * rad));
      this.north.push((lat - this.first.lat) * rad * EARTH_M);
      if (this.east.length > MAX_POINTS) {
        this.east.shift();
        this.north.shift();
      }
    } else this.noFix++;
    const services = SERVICES.filter(([bit]) => (fix.status?.service ?? 0) & bit).map(([, name]) => name);
    const accuracy = horizontalAccuracy(fix);
    const text = `${STATUS[status] ?? `status ${status}`}${services.length ? ` (${services.join(', ')})` : ''} · ` +
      `${Number.isFinite(lat) ? lat.toFixed(7) : '—'}°, ${Number.isFinite(lon) ? lon.toFixed(7) : '—'}° · ` +
      `altitude ${Number.isFinite(fix.altitude) ? `${fix.altitude.toFixed(1)} m` : '—'}` +
      (accuracy !== null ? ` · ±${formatMetres(accuracy)}` : '');
    if (this.status.textContent !== text) this.status.textContent = text;
    this.status.className = `navsat-status ${status >= 0 ? 'ok' : 'error'}`;
    this.plane.invalidate();
  }

  paint(context, width, height) {
    const box = boxOf(this.east, this.north, 10) ?? [-5, 5, -5, 5];
    const view = new View(box, width, height, 0.1);
    drawGrid(context, view);
    const ratio = devicePixelRatio;
    context.strokeStyle = '#26deeb';
    context.lineWidth = 2 * ratio;
    context.beginPath();
    this.east.forEach((e, i) => (i ? context.lineTo : context.moveTo).call(context, view.x(e), view.y(this.north[i])));
    context.stroke();
    const n = this.east.length;
    if (n) {
      const [x, y] = [view.x(this.east[n - 1]), view.y(this.north[n - 1])];
      const accuracy = horizontalAccuracy(this.fix);
      if (accuracy !== null) {
        context.fillStyle = 'rgba(38, 222, 235, 0.15)';
        context.beginPath();
        context.arc(x, y, Math.max(accuracy * view.scale, 2), 0, 2 * Math.PI);
        context.fill();
      }
      context.fillStyle = '#ffc247';
      context.beginPath();
      context.arc(x, y, 5 * ratio, 0, 2 * Math.PI);
      context.fill();
    }
    const text = n ? `${n} fixes · now ${formatMetres(Math.abs(this.east[n - 1]))} ${this.east[n - 1] < 0 ? 'W' : 'E'}, ` +
      `${formatMetres(Math.abs(this.north[n - 1]))} ${this.north[n - 1] < 0 ? 'S' : 'N'} of the first` +
      (this.noFix ? ` · ${this.noFix} without a fix` : '') : `${this.noFix} without a fix`;
    if (this.stats.textContent !== text) this.stats.textContent = text;
  }

  close() {
    this.plane.close();
  }
}

// The horizontal standard deviation (m) from the covariance's east and north variances, or null when unknown.
function horizontalAccuracy(fix) {
  const c = fix?.position_covariance;
  if (!c || !fix.position_covariance_type || c.length < 5) return null;
  const v = (c[0] + c[4]) / 2;
  return Number.isFinite(v) && v >= 0 ? Math.sqrt(v) : null;
}
