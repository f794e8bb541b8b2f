// Driving by holding keys or the joystick. While anything is held a Twist goes out every 100 ms
// (turtlesim stops a turtle 1 s after its last command), so forward + turn combine into arcs; on
// release one zero Twist stops the turtle at once.
const PERIOD_MS = 100;
const DEAD_ZONE = 0.12;  // joystick fraction of its radius that counts as centred
// [forward, left] for each key; `code` is layout-independent (WASD stays in place on AZERTY).
const KEYS = {
  ArrowUp: [1, 0], KeyW: [1, 0],
  ArrowDown: [-1, 0], KeyS: [-1, 0],
  ArrowLeft: [0, 1], KeyA: [0, 1],
  ArrowRight: [0, -1], KeyD: [0, -1],
};

export class Driver {
  // publish(linear, angular) sends a Twist; speeds() gives the full-stick {linear, angular}, or
  // null when the speed inputs are invalid (then nothing is sent).
  constructor({ publish, speeds, joystick }) {
    this.publish = publish;
    this.speeds = speeds;
    this.held = new Set();  // key codes
    this.stick = null;  // [forward, left] in [-1, 1] while the joystick is held
    this.timer = null;
    this.knob = joystick.querySelector('.knob');
    addEventListener('keydown', e => this.onKey(e, true));
    addEventListener('keyup', e => this.onKey(e, false));
    // A key released while the page is in the background never sends keyup: stop instead.
    addEventListener('blur', () => this.stop());
    addEventListener('pagehide', () => this.stop());
    document.addEventListener('visibilitychange', () => document.hidden && this.stop());
    this.bindJoystick(joystick);
  }

  onKey(e, down) {
    const code = e.code in KEYS ? e.code : e.key;
    if (!(code in KEYS)) return;
    if (down && (typing(e.target) || e.ctrlKey || e.metaKey || e.altKey)) return;
    e.preventDefault();  // arrows would scroll the page
    if (down === this.held.has(code)) return;  // auto-repeat, or a keyup we never saw go down
    if (down) this.held.add(code);
    else this.held.delete(code);
    this.update();
  }

  bindJoystick(pad) {
    const move = e => {
      const box = pad.getBoundingClientRect();
      const radius = box.width / 2;
      let dx = (e.clientX - box.left - radius) / radius;
      let dy = (e.clientY - box.top - radius) / radius;
      const length = Math.hypot(dx, dy);
      if (length > 1) [dx, dy] = [dx / length, dy / length];
      this.knob.style.transform = `translate(${dx * radius * 0.6}px, ${dy * radius * 0.6}px)`;
      this.stick = [deadZone(-dy), deadZone(-dx)];
    };
    pad.addEventListener('pointerdown', e => {
      if (e.button !== 0) return;
      pad.setPointerCapture(e.pointerId);
      pad.classList.add('active');
      move(e);
      this.update();
    });
    pad.addEventListener('pointermove', e => this.stick && move(e));
    const release = () => {
      if (!this.stick) return;
      this.stick = null;
      this.knob.style.transform = '';
      pad.classList.remove('active');
      this.update();
    };
    pad.addEventListener('pointerup', release);
    pad.addEventListener('pointercancel', release);
    pad.addEventListener('lostpointercapture', release);
    this.releaseStick = release;
  }

  // [forward, left] demanded right now, each in [-1, 1].
  demand() {
    if (this.stick) return this.stick;
    let forward = 0;
    let left = 0;
    for (const code of this.held) {
      forward += KEYS[code][0];
      left += KEYS[code][1];
    }
    return [Math.sign(forward), Math.sign(left)];
  }

  get driving() {
    return this.timer !== null;
  }

  update() {
    const active = this.held.size > 0 || this.stick !== null;
    if (active) {
      this.send();  // at once, so a tap moves and a change of direction is not 100 ms late
      this.timer ??= setInterval(() => this.send(), PERIOD_MS);
    } else if (this.timer !== null) {
      clearInterval(this.timer);
      this.timer = null;
      this.publish(0, 0);
    }
  }

  send() {
    const speeds = this.speeds();
    if (!speeds) return;
    const [forward, left] = this.demand();
    this.publish(forward * speeds.linear, left * speeds.angular);
  }

  // Lets go of everything (blur, hidden page, lost connection); sends the zero Twist if driving.
  stop() {
    this.held.clear();
    this.releaseStick();
    this.update();
  }
}

function typing(target) {
  return target instanceof HTMLElement &&
    (target.isContentEditable || ['INPUT', 'TEXTAREA', 'SELECT'].includes(target.tagName));
}

function deadZone(v) {
  return Math.abs(v) < DEAD_ZONE ? 0 : v;
}
