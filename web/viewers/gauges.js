// Compact gauges: sensor_msgs/JointState (each joint's position, velocity and effort), Imu (roll, pitch, yaw from
// its orientation, angular velocity, linear acceleration), BatteryState (charge, voltage, current, status, health),
// Range (the distance between its min and max, and its kind). Bars of plain elements, written at the next
// animation frame after a message (the newest), only the values that changed.
import { rpyOf } from '../tf-math.js';

const FRAME_MS = 16;  // at most one message per animation frame (60 Hz): a 40 Hz topic is drawn at 40 Hz

const BATTERY_STATUS = ['unknown', 'charging', 'discharging', 'not charging', 'full'];
const BATTERY_HEALTH = ['unknown', 'good', 'overheat', 'dead', 'overvoltage', 'unspecified failure', 'cold',
  'watchdog timer expired', 'safety timer expired'];
const RADIATION = ['ultrasound', 'infrared'];
const DEG = 180 / Math.PI;

export class GaugesViewer {
  static subscription = { throttle_rate: FRAME_MS, queue_length: 1 };

  constructor(element, { type }) {
    this.type = type;
    element.innerHTML = '<div class="gauges"></div>';
    this.area = element.firstChild;
    this.gauges = new Map();  // key -> { label, bar, value }
    this.message = null;
    this.frame = null;
  }

  draw(message) {
    this.message = message;
    if (this.frame === null) {
      this.frame = requestAnimationFrame(() => {
        this.frame = null;
        this.render(this.message);
      });
    }
  }

  // One gauge: `fraction` (0..1, or null for no bar; `centred`: -1..1 about the middle) and its text.
  gauge(key, label, fraction, text, { centred = false, tone = '' } = {}) {
    let gauge = this.gauges.get(key);
    if (!gauge) {
      const element = document.createElement('div');
      element.className = 'gauge';
      element.dataset.key = key;
      element.innerHTML = '<span class="gauge-label"></span><span class="gauge-track"><span class="gauge-bar">' +
        '</span></span><span class="gauge-value"></span>';
      element.firstChild.textContent = label;
      this.area.append(element);
      gauge = { element, bar: element.querySelector('.gauge-bar'), value: element.querySelector('.gauge-value'),
        style: '' };
      this.gauges.set(key, gauge);
    }
    if (gauge.value.textContent !== text) gauge.value.textContent = text;
    let style = 'width: 0';
    if (fraction !== null && Number.isFinite(fraction)) {
      const f = Math.max(-1, Math.min(1, fraction));
      style = centred ? `left: ${50 + Math.min(0, f) * 50}%; width: ${Math.abs(f) * 50}%`
        : `left: 0; width: ${Math.max(0, f) * 100}%`;
    }
    style += tone ? `; background: var(--${tone})` : '';
    if (gauge.style !== style) {
      gauge.bar.style.cssText = style;
      gauge.style = style;
    }
    gauge.seen = true;
  }

  render(message) {
    for (const gauge of this.gauges.values()) gauge.seen = false;
    const kind = this.type.split('/')[1];
    if (kind === 'JointState') this.joints(message);
    else if (kind === 'Imu') this.imu(message);
    else if (kind === 'BatteryState') this.battery(message);
    else if (kind === 'Range') this.range(message);
    for (const [key, gauge] of this.gauges) {
      if (!gauge.seen) {
        gauge.element.remove();
        this.gauges.delete(key);
      }
    }
  }

  joints({ name = [], position = [], velocity = [], effort = [] }) {
    const n = Math.max(name.length, position.length);
    if (!n) {
      this.gauge('none', 'joints', null, 'none in the message');
      return;
    }
    for (let i = 0; i < n; i++) {
      const label = name[i] ?? `joint ${i}`;
      const p = position[i];
      const angle = Number.isFinite(p) ? `${p.toFixed(3)} (${(p * DEG).toFixed(1)}°)` : '—';
      const extra = [Number.isFinite(velocity[i]) ? `v ${velocity[i].toFixed(2)}` : '',
        Number.isFinite(effort[i]) ? `e ${effort[i].toFixed(2)}` : ''].filter(Boolean).join(' ');
      this.gauge(`joint:${label}`, label, Number.isFinite(p) ? wrap(p) / Math.PI : null,
        `${angle}${extra ? ` · ${extra}` : ''}`, { centred: true });
    }
  }

  imu({ orientation, orientation_covariance: oc, angular_velocity: w, linear_acceleration: a }) {
    const known = orientation && !(oc && oc[0] === -1);
    if (known) {
      const rpy = rpyOf({ x: orientation.x ?? 0, y: orientation.y ?? 0, z: orientation.z ?? 0, w: orientation.w ?? 1 });
      for (const axis of ['roll', 'pitch', 'yaw']) {
        this.gauge(axis, axis, rpy[axis] / Math.PI, `${(rpy[axis] * DEG).toFixed(1)}°`, { centred: true });
      }
    } else this.gauge('orientation', 'orientation', null, 'not given');
    for (const axis of ['x', 'y', 'z']) {
      const v = w?.[axis];
      this.gauge(`w${axis}`, `ω${axis}`, v / 4, Number.isFinite(v) ? `${v.toFixed(2)} rad/s` : '—', { centred: true });
    }
    for (const axis of ['x', 'y', 'z']) {
      const v = a?.[axis];
      this.gauge(`a${axis}`, `a${axis}`, v / 20, Number.isFinite(v) ? `${v.toFixed(2)} m/s²` : '—', { centred: true });
    }
  }

  battery(b) {
    const charge = Number.isFinite(b.percentage) ? b.percentage : null;  // 0..1 (NaN: unmeasured)
    this.gauge('charge', 'charge', charge, charge === null ? 'unknown' : `${(charge * 100).toFixed(0)} %`,
      { tone: charge === null ? '' : charge < 0.15 ? 'bad' : charge < 0.3 ? 'warn' : 'ok' });
    this.gauge('voltage', 'voltage', null, Number.isFinite(b.voltage) ? `${b.voltage.toFixed(2)} V` : '—');
    this.gauge('current', 'current', null, Number.isFinite(b.current) ? `${b.current.toFixed(2)} A` : '—');
    this.gauge('status', 'status', null, `${BATTERY_STATUS[b.power_supply_status] ?? b.power_supply_status} · ` +
      `health ${BATTERY_HEALTH[b.power_supply_health] ?? b.power_supply_health}${b.present === false ? ' · absent' : ''}`);
  }

  range(r) {
    const span = r.max_range - r.min_range;
    const v = r.range;
    const fraction = Number.isFinite(v) && span > 0 ? (v - r.min_range) / span : null;
    const text = v === null || v === undefined || Number.isNaN(v) ? 'no reading'
      : !Number.isFinite(v) ? (v > 0 ? 'nothing in range' : 'too close')
        : `${v.toFixed(3)} m (${(+r.min_range).toFixed(2)}–${(+r.max_range).toFixed(2)} m)`;
    this.gauge('range', 'range', fraction, text);
    this.gauge('kind', RADIATION[r.radiation_type] ?? 'range', null,
      `field of view ${(r.field_of_view * DEG).toFixed(0)}°`);
  }

  close() {
    if (this.frame !== null) cancelAnimationFrame(this.frame);
  }
}

// An angle in -pi..pi.
function wrap(angle) {
  return Math.atan2(Math.sin(angle), Math.cos(angle));
}
